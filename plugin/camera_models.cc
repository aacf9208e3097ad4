// Runtime lookups over COLMAP's camera models (names, parameter counts) and
// double-precision dispatch of the templated projection functions.
#include "plugin/camera_models.h"

namespace watergs {

namespace {

// Static facts about one model, gathered through VisitCameraModel.
struct ModelFacts {
  // COLMAP's name, e.g. "OPENCV".
  std::string name;
  // Number of parameters.
  int num_params = 0;
  // Comma-separated parameter names.
  std::string params_info;
};

ModelFacts FactsOf(int model_id) {
  ModelFacts facts;
  VisitCameraModel(model_id, [&](auto model) {
    using Model = decltype(model);
    facts = {Model::kModelName, Model::kNumParams, Model::kParamsInfo};
  });
  return facts;
}

}  // namespace

bool ExistsCameraModelWithId(int model_id) {
  return model_id >= 0 && model_id < kNumCameraModels;
}

bool ExistsCameraModelWithName(const std::string& model_name) {
  return CameraModelNameToId(model_name) != kInvalidCameraModelId;
}

std::string CameraModelIdToName(int model_id) { return FactsOf(model_id).name; }

int CameraModelNameToId(const std::string& model_name) {
  for (int id = 0; id < kNumCameraModels; ++id) {
    if (FactsOf(id).name == model_name) return id;
  }
  return kInvalidCameraModelId;
}

int CameraModelNumParams(int model_id) { return FactsOf(model_id).num_params; }

std::string CameraModelParamsInfo(int model_id) {
  return FactsOf(model_id).params_info;
}

bool CameraModelHasSingleFocalLength(int model_id) {
  return FactsOf(model_id).params_info.rfind("f,", 0) == 0;
}

void CameraModelWorldToImage(int model_id, const std::vector<double>& params,
                             double u, double v, double* x, double* y) {
  VisitCameraModel(model_id, [&](auto model) {
    decltype(model)::WorldToImage(params.data(), u, v, x, y);
  });
}

void CameraModelImageToWorld(int model_id, const std::vector<double>& params,
                             double x, double y, double* u, double* v) {
  VisitCameraModel(model_id, [&](auto model) {
    decltype(model)::ImageToWorld(params.data(), x, y, u, v);
  });
}

}  // namespace watergs
