// `watergs detect`: the verdict of `extract` for a leak that is not a 3D
// file: screenshots, video frames, photos of a screen. Decodes each image
// file with the frozen decoder (read as every command reads images:
// watermark/image_reading.h), prints each image's bit errors, p-value and
// verdict, then averages the logits over all images into one recovered
// message and tests it exactly as `extract` aggregates its views
// (watermark/view_aggregation.h). A verdict is a result, not an error: the
// exit code is 0 for all of them; unusable input fails in one line naming
// the file. The owner's reading (--raw_path) registers each image to an
// index of the workspace's photos and renders, built once and cached
// (--index_cache, default WS/detect_index/<key>.idx); every call ends with
// one line saying where its time went (indexing, registration, refinement,
// decoding). Its reference, the raw model's render at the registered camera,
// follows the conventions of the renderer that matches the image best
// (--reference_conventions auto: watergs', a web viewer's; issue 54).
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>
#include <vector>

#include "gaussian/depth_render.h"
#include "gaussian/device.h"
#include "gaussian/formats/model_io.h"
#include "gaussian/loss.h"
#include "gaussian/rasterizer.h"
#include "gaussian/render_conventions.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/progress.h"
#include "gaussian/util/text_util.h"
#include "plugin/command.h"
#include "plugin/image_registration.h"
#include "plugin/model_alignment.h"
#include "plugin/option_parser.h"
#include "plugin/photometric_refinement.h"
#include "plugin/reference_conventions.h"
#include "plugin/suspect_reference.h"
#include "plugin/training_views.h"
#include "plugin/workspace.h"
#include "watermark/bit_decoder.h"
#include "watermark/evaluation.h"
#include "watermark/extractor.h"
#include "watermark/image_attacks.h"
#include "watermark/image_reading.h"
#include "watermark/message.h"
#include "watermark/verification.h"
#include "watermark/view_aggregation.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

// Without --max_side, images larger than this on a side are refused: far
// larger than any render the decoder was made for (and a decompression
// bomb's way to exhaust memory).
constexpr int kMaxSideAsIs = 8192;

// The files of --image_path: comma-separated entries, each a file (taken as
// is) or a folder (its .png/.jpg/.jpeg files, sorted by name).
std::vector<std::string> ImageFiles(const std::string& list) {
  std::vector<std::string> files;
  for (const std::string& entry : SplitList(list)) {
    if (fs::is_directory(entry)) {
      const std::vector<std::string> found = ListImageFiles(entry, false);
      if (found.empty()) FailAt(entry, "no .png or .jpg images in the folder");
      files.insert(files.end(), found.begin(), found.end());
    } else {
      if (!fs::exists(entry)) FailAt(entry, "file not found");
      files.push_back(entry);
    }
  }
  if (files.empty()) Fail("--image_path: no image given");
  return files;
}

// The file as the decoder reads it: decoded, refused when it carries no
// signal or is far too large, downscaled (INTER_AREA) to `max_side` on its
// longer side when larger.
ImageRGB LoadImage(const std::string& path, int max_side) {
  cv::Mat rgb = DecodeImageFile(path);
  const int longer = std::max(rgb.cols, rgb.rows);
  if (max_side > 0 && longer > max_side) {
    const double f = double(max_side) / longer;
    const cv::Size size(std::max(1, int(std::lround(rgb.cols * f))),
                        std::max(1, int(std::lround(rgb.rows * f))));
    cv::resize(rgb, rgb, size, 0, 0, cv::INTER_AREA);
  } else if (max_side == 0 && longer > kMaxSideAsIs) {
    FailAt(path, "is " + std::to_string(rgb.cols) + "x" +
                     std::to_string(rgb.rows) + ", far larger than renders (" +
                     std::to_string(kMaxSideAsIs) +
                     " pixels a side at most): downscale it with --max_side");
  }
  // Uniform: every channel within one 8-bit level. Such an image decodes to
  // the decoder's bias alone: it says nothing about a watermark.
  std::vector<cv::Mat> channels;
  cv::split(rgb, channels);
  bool uniform = true;
  for (const cv::Mat& channel : channels) {
    double lo = 0, hi = 0;
    cv::minMaxLoc(channel, &lo, &hi);
    uniform = uniform && hi - lo <= 1.0 / 255 + 1e-6;
  }
  if (uniform) {
    FailAt(path,
           "uniform image (one colour) carries no signal: nothing to decode");
  }
  return ToImageRGB(rgb);
}

std::string Percent(double fraction) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f%%", 100 * fraction);
  return text;
}

// The viewpoints of --index_renders: fixed, so that a reading repeats.
constexpr uint64_t kIndexRenderSeed = 20261128;

// Part of the index cache's key: raise it when the way detect builds its
// index changes (features, lifting, viewpoints), so that no file of the
// old way is read.
constexpr uint32_t kIndexKeyVersion = 1;

// Seconds since `start`.
double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
      .count();
}

// The cache key's pieces, appended as bytes.
class KeyBuilder {
 public:
  template <typename T>
  void Add(const T& value) {
    bytes_.append(reinterpret_cast<const char*>(&value), sizeof(T));
  }
  void Add(const std::string& text) {
    Add(uint64_t(text.size()));
    bytes_ += text;
  }
  // A file's size and FNV-1a 64 (of each 16 MiB chunk, then of those):
  // read in chunks, so that a large model is not held twice in memory.
  void AddFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) FailAt(path, "cannot read");
    std::string chunk(size_t(16) << 20, '\0');
    std::string hashes;
    uint64_t size = 0;
    while (in) {
      in.read(chunk.data(), std::streamsize(chunk.size()));
      const auto got = size_t(in.gcount());
      if (got == 0) break;
      size += got;
      const uint64_t h = Fnv1a64(chunk.data(), got);
      hashes.append(reinterpret_cast<const char*>(&h), sizeof(h));
    }
    Add(size);
    Add(Fnv1a64(hashes.data(), hashes.size()));
  }
  uint64_t Key() const { return Fnv1a64(bytes_.data(), bytes_.size()); }

 private:
  std::string bytes_;
};

// The key of the index detect builds from these inputs: the workspace's
// sparse model files, its views (names, file sizes, camera sizes), the raw
// model file, and every option that shapes the index. Equal keys, equal
// indexes.
uint64_t IndexKey(const Workspace& workspace, const TrainingViews& views,
                  const std::string& raw_path, int index_renders, Device device,
                  const RegistrationOptions& registration) {
  KeyBuilder key;
  key.Add(std::string("watergs detect index"));
  key.Add(kIndexKeyVersion);
  for (const char* stem : {"cameras", "images", "points3D", "rigs", "frames"}) {
    for (const char* extension : {".bin", ".txt"}) {
      const std::string file = std::string(stem) + extension;
      const fs::path path = fs::path(workspace.model_path()) / file;
      if (!fs::is_regular_file(path)) continue;
      key.Add(file);
      key.AddFile(path.string());
    }
  }
  const WorkspaceOptions& wo = workspace.options();
  const std::string scaled = wo.image_path + "_" + std::to_string(wo.downscale);
  key.Add(uint64_t(views.NumViews()));
  for (size_t v = 0; v < views.NumViews(); ++v) {
    key.Add(views.Name(v));
    for (const std::string& folder : {wo.image_path, scaled}) {
      std::error_code error;
      const uintmax_t bytes =
          fs::file_size(fs::path(folder) / views.Name(v), error);
      key.Add(uint64_t(error ? 0 : bytes));
    }
    const RenderCamera camera = views.Camera(v);
    key.Add(int32_t(camera.width));
    key.Add(int32_t(camera.height));
  }
  key.AddFile(raw_path);
  key.Add(int32_t(index_renders));
  key.Add(uint64_t(kIndexRenderSeed));
  key.Add(int32_t(wo.downscale));
  key.Add(registration.associate_px);
  key.Add(uint64_t(registration.skip_views.size()));
  for (size_t v : registration.skip_views) key.Add(uint64_t(v));
  // Renders on another device differ in their last bits, and so may the
  // features found on them.
  key.Add(DeviceName(device));
  return key.Key();
}

// The owner's reading of images without a pose: each image registered to
// the workspace, the raw model rendered at the recovered camera and decoded;
// per image, its logits minus the render's (images that do not register are
// left out, each with a one-line reason).
struct OwnerImages {
  std::vector<ViewDecode> views;  // differences, registered images only
  std::vector<Registration> registrations;     // per image
  std::vector<PhotometricResult> refinements;  // per image
  // The candidate conventions of the reference, and per image the PSNR of
  // each candidate's reference to the image and the one kept (registered
  // images only; empty otherwise).
  std::vector<NamedRenderConventions> candidates;
  std::vector<ReferenceChoice> choices;
  // Per image: the refinement again under the chosen conventions, when
  // they are not the ones of the first refinement (else not applied).
  std::vector<PhotometricResult> rerefinements;
  // Seconds: the index (with reading the raw model, opening the workspace
  // and placing the model in it), registering, refining the poses, and
  // rendering and decoding the raw model's references.
  double indexing_s = 0, registration_s = 0, refinement_s = 0, decoding_s = 0;
  bool index_cached = false;  // read from the cache, not built
  std::string index_file;     // the cache file (empty without a cache)
};

struct OwnerReadingOptions {
  bool refine = true;       // --refine_pose
  int index_renders = 300;  // --index_renders
  // --index_cache: the folder of cached indexes; empty: no cache.
  std::string index_cache;
  // --reference_conventions: "auto" or one name of the registry.
  std::string reference_conventions = "auto";
  // --refine_jacobian: "gradient" (the image gradient and the raw model's
  // depth: one render a solver step) or "renders" (finite differences).
  std::string refine_jacobian = "gradient";
};

OwnerImages ReadAsOwner(const std::vector<std::string>& files,
                        const std::vector<ImageRGB>& images,
                        const std::vector<SuspectProcessing>& processing,
                        const std::vector<ViewDecode>& decoded,
                        const std::string& raw_path,
                        WorkspaceOptions workspace_options, Device device,
                        const OwnerReadingOptions& reading, BitDecoder& decoder,
                        const Bits* expected) {
  OwnerImages out;
  const auto indexing_start = std::chrono::steady_clock::now();
  const ModelData raw = ReadModelFile(raw_path);
  const Workspace workspace = Workspace::Open(workspace_options);
  const WorkspaceViews views(workspace);
  // 8 inliers instead of 15: the photometric refinement then places the
  // camera, and a registration gone wrong only reads random bits (the keyed
  // verdict's rate holds whatever the read). On the demo's 20 JPEG
  // screenshots: 20 registered instead of 17, 17 "present" instead of 16.
  RegistrationOptions registration;
  registration.min_inliers = 8;
  // The index cached by an earlier call on the same inputs, if any.
  std::optional<ImageRegistrar> registrar;
  if (!reading.index_cache.empty()) {
    char key[17];
    std::snprintf(key, sizeof(key), "%016llx",
                  static_cast<unsigned long long>(
                      IndexKey(workspace, views, raw_path,
                               reading.index_renders, device, registration)));
    out.index_file =
        (fs::path(reading.index_cache) / (std::string(key) + ".idx")).string();
    if (fs::exists(out.index_file)) {
      const auto start = std::chrono::steady_clock::now();
      try {
        registrar.emplace(ImageRegistrar::Load(out.index_file, registration));
        out.index_cached = true;
        std::printf("detect: index read from %s (%zu features, %.1f s)\n",
                    out.index_file.c_str(), registrar->IndexSize(),
                    SecondsSince(start));
      } catch (const Error& e) {
        std::fprintf(stderr, "detect: warning: %s; indexing again\n", e.what());
      }
    }
  }
  const bool build = !registrar.has_value();
  if (build) registrar.emplace(workspace, views, registration);
  const std::unique_ptr<Rasterizer> rasterizer = MakeRasterizer(device);
  // Images register in the photos' frame; a raw model saved in another
  // frame is rendered from the cameras moved into it.
  const SimilarityTransform to_model =
      PlaceByOption("detect", "auto", *rasterizer, raw.model, raw_path,
                    workspace, views, {0.f, 0.f, 0.f})
          .placement.workspace_to_model;
  // The raw model's render under each candidate's conventions (the CPU
  // rasterizer for all but watergs' own: the CUDA one implements none).
  out.candidates = ReferenceCandidates(reading.reference_conventions);
  const std::unique_ptr<Rasterizer> cpu_rasterizer = MakeCpuRasterizer();
  auto renderer_for = [&](const RenderConventions& conventions) {
    Rasterizer* chosen =
        conventions.IsDefault() ? rasterizer.get() : cpu_rasterizer.get();
    return CameraRenderer([&, chosen, conventions](const RenderCamera& camera) {
      RenderOptions options;
      options.conventions = conventions;
      ImageRGB image;
      chosen->Forward(raw.model, TransformCamera(camera, to_model), options,
                      &image, nullptr);
      for (float& v : image.data) v = std::clamp(v, 0.f, 1.f);
      return image;
    });
  };
  // The index is built from watergs' renders whatever the reference.
  const CameraRenderer render = renderer_for(RenderConventions());
  const DepthRenderer depth_of = [&](const RenderCamera& camera) {
    std::vector<float> depth =
        RenderDepth(*rasterizer, raw.model, TransformCamera(camera, to_model));
    for (float& d : depth) d /= to_model.scale;  // workspace units
    return depth;
  };
  PhotometricOptions refine_options;
  if (reading.refine_jacobian == "gradient") {
    refine_options.depth_map = depth_of;
  }
  std::vector<CameraRenderer> candidate_renders;
  for (const NamedRenderConventions& c : out.candidates) {
    candidate_renders.push_back(renderer_for(c.conventions));
  }
  if (build && reading.index_renders > 0) {
    ProgressBar bar("detect: indexing renders", reading.index_renders);
    int done = 0;
    registrar->AddRenders(
        SampleFreeViewpoints(views, reading.index_renders, kIndexRenderSeed),
        [&](const RenderCamera& camera) {
          bar.Update(done++);
          return render(camera);
        },
        depth_of);
    bar.Finish(std::to_string(registrar->IndexSize()) +
               " features on the photos and renders");
  }
  if (build && !out.index_file.empty()) {
    // Cached for the next call; a folder that cannot be written (a
    // read-only workspace) costs the cache, never the detection.
    try {
      CreateDirectories(reading.index_cache);
      registrar->Save(out.index_file);
      std::printf("detect: index written to %s (%zu features)\n",
                  out.index_file.c_str(), registrar->IndexSize());
    } catch (const Error& e) {
      std::fprintf(stderr,
                   "detect: warning: the index is not cached (%s); going on "
                   "without\n",
                   e.what());
      out.index_file.clear();
    }
  }
  out.indexing_s = SecondsSince(indexing_start);
  for (size_t k = 0; k < files.size(); ++k) {
    // The raw model's render as this file went (its size, its JPEG), under
    // each candidate's conventions; the pose is refined under the first.
    std::vector<CameraRenderer> like_file;
    for (const CameraRenderer& candidate : candidate_renders) {
      like_file.push_back([&, candidate](const RenderCamera& camera) {
        return RenderLikeSuspect(candidate, camera, processing[k]);
      });
    }
    auto start = std::chrono::steady_clock::now();
    Registration r = registrar->Register(images[k]);
    out.registration_s += SecondsSince(start);
    PhotometricResult refined;
    if (r.registered && reading.refine) {
      start = std::chrono::steady_clock::now();
      // Every pose the matches support: the one the render fits best wins.
      std::vector<RenderCamera> starts = {r.camera, r.guessed_camera};
      starts.insert(starts.end(), r.alternatives.begin(), r.alternatives.end());
      refined = RefinePhotometrically(images[k], starts, r.depth, like_file[0],
                                      refine_options);
      r.camera = refined.camera;
      out.refinement_s += SecondsSince(start);
    }
    out.refinements.push_back(refined);
    ReferenceChoice choice;
    PhotometricResult rerefined;
    if (r.registered) {
      start = std::chrono::steady_clock::now();
      std::vector<ImageRGB> references;
      for (const CameraRenderer& candidate : like_file) {
        references.push_back(candidate(r.camera));
      }
      choice = ChooseReference(images[k], references);
      out.decoding_s += SecondsSince(start);
      if (choice.best != 0 && reading.refine) {
        // The first refinement fitted another renderer's image: the pose
        // again, under the conventions that match the image.
        start = std::chrono::steady_clock::now();
        rerefined =
            RefinePhotometrically(images[k], {r.camera}, r.depth,
                                  like_file[choice.best], refine_options);
        if (rerefined.applied) {
          r.camera = rerefined.camera;
          references[choice.best] = like_file[choice.best](r.camera);
          choice.psnr[choice.best] = Psnr(references[choice.best], images[k]);
        }
        out.refinement_s += SecondsSince(start);
      }
      start = std::chrono::steady_clock::now();
      ViewDecode reference;
      reference.name = files[k];
      reference.logits = decoder.Logits(references[choice.best]);
      std::vector<ViewDecode> one =
          DifferenceViews({decoded[k]}, {reference}, expected);
      out.views.push_back(std::move(one[0]));
      out.decoding_s += SecondsSince(start);
    }
    out.choices.push_back(choice);
    out.rerefinements.push_back(rerefined);
    out.registrations.push_back(std::move(r));
  }
  return out;
}

// Image k's reference: "<name> at <PSNR> dB" and, with several candidates,
// the others' PSNR and the second refinement's motion.
std::string ReferenceText(const OwnerImages& owner, size_t k) {
  const ReferenceChoice& choice = owner.choices[k];
  char text[96];
  std::snprintf(text, sizeof(text), "%s at %.2f dB",
                owner.candidates[choice.best].name.c_str(),
                choice.psnr[choice.best]);
  std::string out = text;
  if (owner.candidates.size() < 2) return out;
  std::string others;
  for (size_t c = 0; c < owner.candidates.size(); ++c) {
    if (c == choice.best) continue;
    std::snprintf(text, sizeof(text), "%s%s %.2f", others.empty() ? "" : ", ",
                  owner.candidates[c].name.c_str(), choice.psnr[c]);
    others += text;
  }
  out += " (" + others;
  const PhotometricResult& again = owner.rerefinements[k];
  if (again.applied) {
    std::snprintf(text, sizeof(text), "; refined again by %.2f px",
                  again.moved_px);
    out += text;
  }
  return out + ")";
}

int RunDetect(int argc, char** argv) {
  const auto run_start = std::chrono::steady_clock::now();
  std::string raw_path;
  WorkspaceOptions workspace_options;
  std::string image_path, decoder_path, message, key_option, json_path;
  double present_p = VerificationThresholds().present_p;
  int max_side = 0;
  int decode_width = 0;
  int num_threads = 0;
  OwnerReadingOptions reading;
  OptionParser parser(
      "detect",
      "Decodes the WATER-GS watermark from image files (screenshots, video "
      "frames, photos of a screen: a leak that is not a 3D file) and tests "
      "it against a claimed message as extract does: each image's bit "
      "errors, p-value and verdict, then the logits averaged over all "
      "images: binomial p-value under the null hypothesis of unmarked "
      "images; 'watermark present' at p <= --false_positive_rate, 'absent' "
      "above p = 0.01, 'inconclusive' between.");
  decoder_path = ShippedDecoderPath();
  parser.Add("decoder", &decoder_path, kDecoderHelp);
  parser.AddRequired("image_path", &image_path,
                     "Image files (PNG/JPEG, 8 or 16 bits) and folders of "
                     "them, comma-separated; a folder: its image files, "
                     "sorted by name");
  parser.Add("message", &message,
             std::string("Claimed message: ") + kMessageFormats);
  parser.Add("key", &key_option, kKeyHelp);
  parser.Add("false_positive_rate", &present_p,
             "p-value at or below which the watermark is declared present");
  parser.Add("max_side", &max_side,
             "Downscale (INTER_AREA) images whose longer side exceeds N "
             "pixels to N (0 = decode as is; images over " +
                 std::to_string(kMaxSideAsIs) + " pixels are then refused)");
  parser.Add("decode_width", &decode_width,
             "Resize each image to this width (aspect kept) before decoding: "
             "the width of the renders the model was watermarked at, for "
             "copies shared smaller or larger (0 = decode as is)");
  parser.Add("raw_path", &raw_path,
             "The unwatermarked model (the owner's): register each image to "
             "--workspace_path, render this model at the recovered camera and "
             "also read each bit from the difference (the owner's reading)");
  parser.Add("workspace_path", &workspace_options.workspace_path,
             "COLMAP workspace the images are registered to (with "
             "--raw_path)");
  parser.Add("index_renders", &reading.index_renders,
             "Renders of the raw model at this many viewpoints between the "
             "workspace's cameras, added to the registration index: an image "
             "taken far from every photo registers to a render near it "
             "(rendered at the workspace cameras' size; detect prints how "
             "many images registered; 0 = the photos only)");
  parser.Add("index_cache", &reading.index_cache,
             "Folder where the registration index (the photos' and "
             "--index_renders' features) is kept between calls, one file "
             "per workspace, raw model and options: built once (minutes), "
             "then read in seconds (default <workspace_path>/detect_index; "
             "given empty, --index_cache \"\", no cache; a folder that "
             "cannot be written only warns)");
  parser.Add("refine_pose", &reading.refine,
             "After registration, move each camera to where the raw model's "
             "render matches the image best (photometric least squares): "
             "the difference reading needs the render within a fraction of "
             "a pixel");
  parser.Add("refine_jacobian", &reading.refine_jacobian,
             "How the refinement finds its steps: gradient (the render's "
             "image gradient and the raw model's depth, one render a step) "
             "or renders (finite differences, 7-10 renders a step)");
  parser.Add("reference_conventions", &reading.reference_conventions,
             "The renderer the raw model's reference imitates: auto (each "
             "in turn, per image the one whose render matches the "
             "registered image best, the pose refined again under it) or "
             "one of them (" +
                 RenderConventionsHelp() + ")");
  parser.Add("sparse_path", &workspace_options.input_path,
             "Sparse model folder (default <workspace>/sparse/0)");
  parser.Add("workspace_images", &workspace_options.image_path,
             "The workspace's photos (default <workspace>/images)");
  parser.Add("downscale", &workspace_options.downscale,
             "Workspace image downscale: 1,2,4,8 (the scale the model was "
             "trained at)");
  parser.Add("num_threads", &num_threads, "Threads (0 = all cores)");
  parser.Add("json", &json_path, "Write the result as JSON to this file");
  if (!parser.Parse(argc, argv)) return 0;
  if (raw_path.empty() != workspace_options.workspace_path.empty()) {
    Fail(
        "detect: --raw_path and --workspace_path go together (the owner's "
        "reading registers each image to the workspace)");
  }
  if (!(present_p > 0 && present_p < 0.01)) {
    Fail("--false_positive_rate must be in (0, 0.01)");
  }
  if (max_side < 0) Fail("--max_side must be >= 0");
  if (reading.index_renders < 0 || reading.index_renders > 100000) {
    Fail("--index_renders must be in [0, 100000]");
  }
  if (decode_width < 0 || decode_width > kMaxSideAsIs) {
    Fail("--decode_width must be in [0, " + std::to_string(kMaxSideAsIs) + "]");
  }
  ReferenceCandidates(reading.reference_conventions);  // fails on a typo
  if (reading.refine_jacobian != "gradient" &&
      reading.refine_jacobian != "renders") {
    Fail("detect: --refine_jacobian gradient or renders, not '" +
         reading.refine_jacobian + "'");
  }
  if (num_threads > 0) omp_set_num_threads(num_threads);
  if (!json_path.empty()) CheckOutputFile(json_path);
  if (!parser.Given("index_cache") && !raw_path.empty()) {
    reading.index_cache =
        (fs::path(workspace_options.workspace_path) / "detect_index").string();
  }

  const std::vector<std::string> files = ImageFiles(image_path);
  const std::unique_ptr<BitDecoder> decoder =
      LoadBitDecoder(decoder_path, parser.device());
  const int num_bits = decoder->NumBits();
  Bits expected;
  if (!message.empty()) {
    expected =
        ApplyKey(ParseMessage(message, num_bits), ResolveKey(key_option));
  }
  VerificationThresholds thresholds;
  thresholds.present_p = present_p;

  // Every image is decoded before anything is printed: unusable input
  // fails in one line.
  std::vector<ViewDecode> views;
  std::vector<std::pair<int, int>> sizes;
  std::vector<ImageRGB> decoded_images;       // kept for the owner's reading
  std::vector<SuspectProcessing> processing;  // for the owner's reference
  const auto decoding_start = std::chrono::steady_clock::now();
  for (const std::string& path : files) {
    ImageRGB image = LoadImage(path, max_side);
    processing.push_back({image.width, image.height, JpegQualityOf(path)});
    if (decode_width > 0 && image.width != decode_width) {
      // Back to the scale the watermark was embedded at (aspect kept).
      const int height = std::max(
          1,
          int(std::lround(double(image.height) * decode_width / image.width)));
      image = ResizeTo(image, decode_width, height);
    }
    ViewDecode view;
    view.name = path;
    try {
      view.logits = decoder->Logits(image);
    } catch (const Error& e) {
      FailAt(path, e.what());  // e.g. smaller than the decoder's pooling
    }
    sizes.emplace_back(image.width, image.height);
    views.push_back(std::move(view));
    if (!raw_path.empty()) decoded_images.push_back(std::move(image));
  }
  const double decoding_s = SecondsSince(decoding_start);
  OwnerImages owner;
  if (!raw_path.empty()) {
    owner = ReadAsOwner(files, decoded_images, processing, views, raw_path,
                        workspace_options, parser.device(), reading, *decoder,
                        expected.empty() ? nullptr : &expected);
  }
  std::printf("detect: %zu images, %d-bit decoder %s\n", files.size(), num_bits,
              decoder_path.c_str());
  for (size_t k = 0; k < views.size(); ++k) {
    const ViewDecode& view = views[k];
    Bits bits(num_bits);
    for (int i = 0; i < num_bits; ++i) bits[i] = view.logits[i] > 0;
    if (expected.empty()) {
      std::printf("detect: %s (%dx%d): hex %s\n", view.name.c_str(),
                  sizes[k].first, sizes[k].second, BitsToHex(bits).c_str());
    } else {
      const int errors = HammingDistance(bits, expected);
      const double p = BinomialTailPValue(num_bits - errors, num_bits);
      std::printf(
          "detect: %s (%dx%d): %d of %d bits wrong (BER %s), p-value %.3g, "
          "%s\n",
          view.name.c_str(), sizes[k].first, sizes[k].second, errors, num_bits,
          Percent(double(errors) / num_bits).c_str(), p,
          ToString(Decide(p, thresholds)).c_str());
    }
  }

  const ExtractionResult r =
      AggregateViews(std::move(views), num_bits,
                     expected.empty() ? nullptr : &expected, thresholds);
  std::printf("detect: all %zu images (mean logits): recovered hex %s\n",
              r.views.size(), BitsToHex(r.recovered).c_str());
  std::printf("detect: recovered bits %s\n", BitsToString(r.recovered).c_str());
  const ViewBerSpread spread = SpreadOfViewBer(r);
  if (r.has_expected) {
    std::printf("detect: expected bits  %s\n",
                BitsToString(r.expected).c_str());
    std::printf(
        "detect: BER %s (%d of %d bits); single-image BER mean %s median %s "
        "p90 %s min %s max %s\n",
        Percent(r.ber).c_str(), r.bit_errors, num_bits,
        Percent(spread.mean).c_str(), Percent(spread.median).c_str(),
        Percent(spread.p90).c_str(), Percent(spread.min).c_str(),
        Percent(spread.max).c_str());
    std::printf(
        "detect: p-value %.3g (chance of this many matching bits from "
        "unmarked images)\n",
        r.p_value);
    std::printf("detect: verdict: %s (false-positive rate %.0e)\n",
                ToString(r.verdict).c_str(), present_p);
  }
  ExtractionResult owned;
  if (!raw_path.empty()) {
    for (size_t k = 0; k < files.size(); ++k) {
      const Registration& g = owner.registrations[k];
      if (!g.registered) {
        std::printf("detect (owner's reading): %s: not registered: %s\n",
                    files[k].c_str(), g.why.c_str());
      }
    }
    if (owner.views.empty()) {
      std::printf("detect (owner's reading): no image registered\n");
    } else {
      size_t next = 0;
      for (size_t k = 0; k < files.size(); ++k) {
        const Registration& g = owner.registrations[k];
        if (!g.registered || expected.empty()) continue;
        const ViewDecode& v = owner.views[next++];
        Bits bits(num_bits);
        for (int i = 0; i < num_bits; ++i) bits[i] = v.logits[i] > 0;
        const int errors = HammingDistance(bits, expected);
        const double p = BinomialTailPValue(num_bits - errors, num_bits);
        const PhotometricResult& f = owner.refinements[k];
        char moved[80] = "";
        if (f.applied) {
          // Starts 0-1: the registered pose; 2 on: another pose the matches
          // supported (Registration::alternatives).
          std::snprintf(
              moved, sizeof(moved), ", refined by %.2f px%s", f.moved_px,
              f.start >= 2 ? " from another pose the matches support" : "");
        }
        std::printf(
            "detect (owner's reading): %s: registered (%d inliers of %d "
            "matches, %.2f px%s), reference %s: %d of %d bits wrong (BER %s), "
            "p-value %.3g, %s\n",
            files[k].c_str(), g.inliers, g.matches, g.rms_px, moved,
            ReferenceText(owner, k).c_str(), errors, num_bits,
            Percent(double(errors) / num_bits).c_str(), p,
            ToString(Decide(p, thresholds)).c_str());
      }
      owned =
          AggregateViews(owner.views, num_bits,
                         expected.empty() ? nullptr : &expected, thresholds);
      if (owned.has_expected) {
        const ViewBerSpread s = SpreadOfViewBer(owned);
        std::printf(
            "detect (owner's reading): %zu of %zu images registered: BER %s "
            "(%d of %d bits); single-image BER mean %s p90 %s\n",
            owned.views.size(), files.size(), Percent(owned.ber).c_str(),
            owned.bit_errors, num_bits, Percent(s.mean).c_str(),
            Percent(s.p90).c_str());
        std::printf(
            "detect (owner's reading): verdict: %s (false-positive rate "
            "%.0e)\n",
            ToString(owned.verdict).c_str(), present_p);
      }
    }
  }
  // Where the time went (issue 54: the index is the slow part; cached, each
  // image costs its registration, refinement and decoding).
  const double total_s = SecondsSince(run_start);
  const char* index_state = raw_path.empty()     ? "none"
                            : owner.index_cached ? "cached"
                                                 : "built";
  const double all_decoding_s = decoding_s + owner.decoding_s;
  const double per_image_s =
      total_s / double(std::max<size_t>(1, files.size()));
  std::printf(
      "detect: time: indexing %.1f s (%s), registration %.1f s, refinement "
      "%.1f s, decoding %.1f s over %zu images (%.1f s an image)\n",
      owner.indexing_s, index_state, owner.registration_s, owner.refinement_s,
      all_decoding_s, files.size(), per_image_s);
  if (!json_path.empty()) {
    // extract's JSON, with each image's bits, logits, p-value and verdict,
    // and the whole single-image BER distribution.
    nlohmann::json j = nlohmann::json::parse(ExtractionToJson(r));
    j["command"] = "detect";
    j["num_images"] = r.views.size();
    if (r.has_expected) {
      j["view_ber"] = {{"mean", spread.mean},
                       {"median", spread.median},
                       {"p90", spread.p90},
                       {"min", spread.min},
                       {"max", spread.max}};
    }
    nlohmann::json images = nlohmann::json::array();
    for (size_t k = 0; k < r.views.size(); ++k) {
      const ViewDecode& v = r.views[k];
      Bits bits(num_bits);
      for (int i = 0; i < num_bits; ++i) bits[i] = v.logits[i] > 0;
      nlohmann::json e = {{"name", v.name},
                          {"width", sizes[k].first},
                          {"height", sizes[k].second},
                          {"bits", BitsToString(bits)},
                          {"logits", v.logits}};
      if (v.bit_errors >= 0) {
        const double p = BinomialTailPValue(num_bits - v.bit_errors, num_bits);
        e["bit_errors"] = v.bit_errors;
        e["p_value"] = p;
        e["verdict"] = ToString(Decide(p, thresholds));
      }
      images.push_back(e);
    }
    j["views"] = images;
    if (!raw_path.empty()) {
      nlohmann::json o = owned.views.empty()
                             ? nlohmann::json::object()
                             : nlohmann::json::parse(ExtractionToJson(owned));
      o["raw_path"] = raw_path;
      nlohmann::json reg = nlohmann::json::array();
      for (size_t k = 0; k < files.size(); ++k) {
        const Registration& g = owner.registrations[k];
        nlohmann::json e = {{"name", files[k]},
                            {"registered", g.registered},
                            {"matches", g.matches},
                            {"inliers", g.inliers}};
        if (g.registered) {
          e["rms_px"] = g.rms_px;
          const PhotometricResult& f = owner.refinements[k];
          e["refinement"] = {
              {"applied", f.applied},     {"moved_px", f.moved_px},
              {"start", f.start},         {"rms_before", f.rms_before},
              {"rms_after", f.rms_after}, {"renders", f.renders}};
          const ReferenceChoice& choice = owner.choices[k];
          nlohmann::json psnr = nlohmann::json::object();
          for (size_t c = 0; c < owner.candidates.size(); ++c) {
            psnr[owner.candidates[c].name] = choice.psnr[c];
          }
          const PhotometricResult& again = owner.rerefinements[k];
          e["reference"] = {{"conventions", owner.candidates[choice.best].name},
                            {"psnr", psnr},
                            {"refined_again", again.applied},
                            {"refined_again_px", again.moved_px},
                            {"refined_again_renders", again.renders}};
          const RenderCamera& c = g.camera;
          e["camera"] = {
              {"fx", c.fx},
              {"fy", c.fy},
              {"cx", c.cx},
              {"cy", c.cy},
              {"center", {c.Center().x(), c.Center().y(), c.Center().z()}}};
        } else {
          e["why"] = g.why;
        }
        reg.push_back(e);
      }
      o["registrations"] = reg;
      j["owner"] = o;
    }
    j["time"] = {{"indexing_s", owner.indexing_s},
                 {"index", index_state},
                 {"index_file", owner.index_file},
                 {"registration_s", owner.registration_s},
                 {"refinement_s", owner.refinement_s},
                 {"decoding_s", all_decoding_s},
                 {"images", files.size()},
                 {"per_image_s", per_image_s},
                 {"total_s", total_s}};
    j["provenance"] = Provenance(argc, argv);
    AtomicWriteFile(json_path, j.dump(2) + "\n");
  }
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(detect,
                "Detects a WATER-GS watermark in image files (screenshots, "
                "frames, photos of a screen)",
                watergs::RunDetect);
