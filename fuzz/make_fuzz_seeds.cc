// Writes the fuzz targets' seed corpora: small valid inputs of every format,
// made with the project's own writers from the committed demo scene and from
// small synthetic models, so that no binary seed needs to be committed.
//   watergs_fuzz_seeds <out_dir>   ->  <out_dir>/<target>/<seed>
#include <zip.h>
#include <zlib.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>
#include <sstream>

#include "fuzz/fuzz_support.h"
#include "gaussian/checkpoint.h"
#include "gaussian/formats/compressed_ply_io.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/formats/sog_io.h"
#include "gaussian/formats/splat_io.h"
#include "gaussian/formats/spz_io.h"
#include "gaussian/util/file_util.h"
#include "plugin/camera_models.h"
#include "watermark/hidden_model.h"
#include "watermark/network_file.h"

namespace watergs::fuzz {
namespace {

namespace fs = std::filesystem;

std::string SeedPath(const std::string& out, const std::string& target,
                     const std::string& name) {
  CreateDirectories(out + "/" + target);
  return out + "/" + target + "/" + name;
}

void WritePlySeeds(const std::string& out) {
  WritePly(SeedPath(out, "ply", "inria_sh0.ply"), SmallModel(3, 0, 1));
  WritePly(SeedPath(out, "ply", "inria_sh1.ply"), SmallModel(2, 1, 2));
  WritePly(SeedPath(out, "ply", "inria_sh3.ply"), SmallModel(1, 3, 3));
  WritePly(SeedPath(out, "ply", "empty.ply"), SmallModel(0, 0, 4));
  PlyLayout ascii = InriaPlyLayout(0, 2);
  ascii.format = PlyFormat::kAscii;
  ascii.comments.push_back({"comment written by watergs_fuzz_seeds", 0});
  WritePly(SeedPath(out, "ply", "ascii_sh0.ply"), SmallModel(2, 0, 5), ascii);
  // Big-endian, CRLF, double and integer properties, an extra property.
  PlyLayout mixed = InriaPlyLayout(1, 2);
  mixed.format = PlyFormat::kBinaryBigEndian;
  mixed.line_ending = "\r\n";
  mixed.properties[0].type = PlyType::kFloat64;
  mixed.properties[0].type_name = "double";
  mixed.properties[3].type = PlyType::kUint8;
  mixed.properties[3].type_name = "uchar";
  mixed.properties.push_back({"confidence", PlyType::kInt16, "int16"});
  mixed.ZeroExtras(2);
  WritePly(SeedPath(out, "ply", "mixed_sh1.ply"), SmallModel(2, 1, 6), mixed);
}

// A bundled SOG as sog_fuzzer's split input: meta.json, then the images in
// the order the decoder reads them.
std::string SplitSog(const std::string& bundle) {
  zip_error_t error;
  zip_error_init(&error);
  zip_source_t* source =
      zip_source_buffer_create(bundle.data(), bundle.size(), 0, &error);
  zip_t* archive = zip_open_from_source(source, ZIP_RDONLY, &error);
  if (archive == nullptr) Fail("seeds: cannot reopen a SOG");
  std::string split;
  for (const char* file :
       {"meta.json", "means_l.webp", "means_u.webp", "quats.webp",
        "scales.webp", "sh0.webp", "shN_centroids.webp", "shN_labels.webp"}) {
    zip_file_t* member = zip_fopen(archive, file, 0);
    if (member == nullptr) continue;  // no SH bands
    if (!split.empty()) split += fuzz::kSogFuzzSeparator;
    char buffer[4096];
    zip_int64_t got = 0;
    while ((got = zip_fread(member, buffer, sizeof buffer)) > 0) {
      split.append(buffer, size_t(got));
    }
    zip_fclose(member);
  }
  zip_discard(archive);
  return split;
}

// The quantised formats, from the project's own writers.
void WriteCodecSeeds(const std::string& out) {
  for (int degree = 0; degree <= 3; ++degree) {
    const GaussianModel model = SmallModel(3 + degree, degree, 20 + degree);
    const std::string name = "sh" + std::to_string(degree);
    WriteSpz(SeedPath(out, "spz", name + "_v3.spz"), model);
    WriteSpz(SeedPath(out, "spz", name + "_v2.spz"), model, {2});
    WriteCompressedPly(
        SeedPath(out, "compressed_ply", name + ".compressed.ply"), model);
  }
  WriteSpz(SeedPath(out, "spz", "empty.spz"), SmallModel(0, 0, 30));
  WriteCompressedPly(SeedPath(out, "compressed_ply", "empty.compressed.ply"),
                     SmallModel(0, 1, 31));
  // More than one chunk of 256.
  WriteCompressedPly(SeedPath(out, "compressed_ply", "chunks.compressed.ply"),
                     SmallModel(300, 0, 32));
  WriteSplat(SeedPath(out, "splat", "one.splat"), SmallModel(1, 0, 33));
  WriteSplat(SeedPath(out, "splat", "five.splat"), SmallModel(5, 2, 34));
  for (int degree : {0, 1, 3}) {
    const GaussianModel model = SmallModel(5 + degree, degree, 40 + degree);
    const std::string bundle = EncodeSog(model);
    const std::string name = "sh" + std::to_string(degree);
    AtomicWriteFile(SeedPath(out, "sog", name + ".sog"), bundle);
    AtomicWriteFile(SeedPath(out, "sog", name + ".split"), SplitSog(bundle));
  }
  AtomicWriteFile(SeedPath(out, "sog", "empty.sog"),
                  EncodeSog(SmallModel(0, 0, 44)));
}

void WriteColmapSeeds(const std::string& out) {
  const Reconstruction subset = DemoSubset();
  AtomicWriteFile(SeedPath(out, "cameras_bin", "demo.bin"),
                  CamerasBinary(subset));
  AtomicWriteFile(SeedPath(out, "images_bin", "demo.bin"),
                  ImagesBinary(subset));
  AtomicWriteFile(SeedPath(out, "points3D_bin", "demo.bin"),
                  Points3DBinary(subset));
  AtomicWriteFile(SeedPath(out, "cameras_txt", "demo.txt"),
                  CamerasText(subset));
  AtomicWriteFile(SeedPath(out, "images_txt", "demo.txt"), ImagesText(subset));
  AtomicWriteFile(SeedPath(out, "points3D_txt", "demo.txt"),
                  Points3DText(subset));
  // One camera of every COLMAP model, so that each parameter layout is seen.
  Reconstruction all_models;
  for (int model_id = 0; model_id < kNumCameraModels; ++model_id) {
    Camera camera;
    camera.camera_id = static_cast<camera_t>(model_id + 1);
    camera.model_id = model_id;
    camera.width = 640;
    camera.height = 480;
    camera.params.assign(CameraModelNumParams(model_id), 0.01);
    for (int i = 0; i < 4 && i < CameraModelNumParams(model_id); ++i) {
      camera.params[i] = 300.0 + i;
    }
    all_models.AddCamera(camera);
  }
  AtomicWriteFile(SeedPath(out, "cameras_bin", "all_models.bin"),
                  CamerasBinary(all_models));
  AtomicWriteFile(SeedPath(out, "cameras_txt", "all_models.txt"),
                  CamerasText(all_models));
}

// DensityStrategy::SaveState's bytes for n Gaussians: three u64-counted
// vectors (gradient sums, counts, max radii) and the RNG in text form.
std::string DensityState(size_t n) {
  std::string bytes;
  for (size_t element_size : {sizeof(float), sizeof(uint16_t), sizeof(float)}) {
    const uint64_t count = n;
    bytes.append(reinterpret_cast<const char*>(&count), sizeof(count));
    bytes.append(n * element_size, '\0');
  }
  std::ostringstream rng;
  rng << std::mt19937_64(42);
  return bytes + rng.str();
}

// A training checkpoint shaped as the trainer writes one (Adam moments per
// group, full or compact), or (embed = true) as the embedder does, with its
// JSON state in rng_state.
TrainingCheckpoint SmallCheckpoint(bool compact_moments, bool embed) {
  TrainingCheckpoint c;
  c.iteration = 7;
  c.active_sh_degree = 1;
  c.elapsed_seconds = 1.5;
  c.model = SmallModel(2, 1, 7);
  const size_t n = c.model.size();
  const int strides[kNumParamGroups] = {3, 3, c.model.sh_rest_stride(),
                                        1, 3, 4};
  for (int g = 0; g < kNumParamGroups; ++g) {
    AdamGroupState& state = c.adam[g];
    if (compact_moments) {
      state.exp_avg_q.assign(n * strides[g], 3);
      state.exp_avg_sq_shared.assign(n, 0.25f);
    } else {
      state.exp_avg.assign(n * strides[g], 0.5f);
      state.exp_avg_sq.assign(n * strides[g], 0.25f);
    }
    state.step = 7;
  }
  c.density_state = DensityState(n);
  std::ostringstream rng;
  rng << std::mt19937_64(42);
  c.rng_state = embed ? "{\"origin\":[0,1],\"rng\":\"1 2 3\"}" : rng.str();
  c.view_stack = {1, 0};
  c.run_signature = "{\"iterations\":30000}";
  return c;
}

void WriteCheckpointSeeds(const std::string& out) {
  WriteCheckpoint(SeedPath(out, "checkpoint", "train.ckpt"),
                  SmallCheckpoint(false, false));
  WriteCheckpoint(SeedPath(out, "checkpoint", "train_compact.ckpt"),
                  SmallCheckpoint(true, false));
  WriteCheckpoint(SeedPath(out, "checkpoint", "embed.ckpt"),
                  SmallCheckpoint(false, true));
}

void WriteNetworkSeeds(const std::string& out) {
  HiddenConfig config;
  config.num_bits = 8;
  config.channels = 2;
  config.encoder_blocks = 1;
  config.decoder_blocks = 1;
  HiddenModel model(config, /*with_encoder=*/true, 1);
  WriteNetworkFile(SeedPath(out, "network_file", "hidden_decoder.bin"),
                   HiddenModelToFile(model, false));
  WriteNetworkFile(SeedPath(out, "network_file", "hidden_both.bin"),
                   HiddenModelToFile(model, true));
  NetworkFile plain;
  plain.kind = "hidden-checkpoint";
  plain.meta = {{"step", 3}, {"num_bits", 8}};
  plain.tensors = {{"scalar", {}, {1.f}},
                   {"matrix", {2, 3}, {1, 2, 3, 4, 5, 6}},
                   {"empty", {0, 4}, {}}};
  WriteNetworkFile(SeedPath(out, "network_file", "plain.bin"), plain);
}

void WriteTextSeed(const std::string& path, const std::string& text) {
  AtomicWriteFile(path, text);
}

void WriteMessageSeeds(const std::string& out) {
  // First byte 12: 49-bit decoder (see message_fuzzer.cc).
  const std::string l = "\x0c";
  int i = 0;
  for (const char* text : {"hex:0123456789ab", "0xDEADBEEF", "bits:010011",
                           "text:hello", "h\xc3\xa9llo", "WATERGS"}) {
    WriteTextSeed(SeedPath(out, "message", "seed" + std::to_string(i++)),
                  l + text);
  }
}

void WriteProjectIniSeeds(const std::string& out) {
  WriteTextSeed(SeedPath(out, "project_ini", "full.ini"),
                "# a project file\nmodel_path = scene/model.ply\n"
                "output_path = out\niterations = 100\nseed = -3\n"
                "lambda = 0.5e-1\nquiet = true\n");
  WriteTextSeed(SeedPath(out, "project_ini", "minimal.ini"), "output_path=o\n");
}

void WriteSimilaritySeeds(const std::string& out) {
  WriteTextSeed(SeedPath(out, "similarity", "z_axis"), "30,1,0,0,2");
  WriteTextSeed(SeedPath(out, "similarity", "axis"),
                "-12.5,0.1,-2e-3,4,0.75,1,1,0");
}

// A small weights file in the LPIPS format (magic, tensor records, CRC-32):
// the input scaling only, so the reader parses it and Load refuses it as
// incomplete, the deepest path a mutated file can reach.
void WriteLpipsSeeds(const std::string& out) {
  std::string blob = "WGLPIPS1";
  const auto put = [&blob](const void* p, size_t n) {
    blob.append(static_cast<const char*>(p), n);
  };
  const uint32_t count = 2;
  put(&count, 4);
  for (const char* name : {"scaling.shift", "scaling.scale"}) {
    const uint32_t name_size = uint32_t(std::strlen(name)), ndim = 1;
    const int64_t dim = 3;
    const float values[3] = {0.5f, 0.25f, 0.125f};
    put(&name_size, 4);
    put(name, name_size);
    put(&ndim, 4);
    put(&dim, 8);
    put(values, sizeof(values));
  }
  const uint32_t crc = uint32_t(crc32(
      0L, reinterpret_cast<const Bytef*>(blob.data()), uInt(blob.size())));
  put(&crc, 4);
  WriteTextSeed(SeedPath(out, "lpips_weights", "scaling_only.bin"), blob);
}

}  // namespace
}  // namespace watergs::fuzz

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <out_dir>\n", argv[0]);
    return 2;
  }
  const std::string out = argv[1];
  try {
    watergs::fuzz::WritePlySeeds(out);
    watergs::fuzz::WriteCodecSeeds(out);
    watergs::fuzz::WriteColmapSeeds(out);
    watergs::fuzz::WriteCheckpointSeeds(out);
    watergs::fuzz::WriteNetworkSeeds(out);
    watergs::fuzz::WriteMessageSeeds(out);
    watergs::fuzz::WriteProjectIniSeeds(out);
    watergs::fuzz::WriteSimilaritySeeds(out);
    watergs::fuzz::WriteLpipsSeeds(out);
  } catch (const watergs::Error& e) {
    std::fprintf(stderr, "watergs_fuzz_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}
