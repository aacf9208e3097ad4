// `watergs encode_images`: the "HiDDeN + 3DGS" baseline's first step
// (paper Sec. 5): writes every image of a folder watermarked by a HiDDeN
// encoder, under the same file name, losslessly (PNG data even under a .jpg
// name: JPEG's chroma subsampling would erase much of the watermark before
// 3DGS sees it; OpenCV and COLMAP read files by content), so that `train
// --image_path OUT` trains 3DGS on the watermarked dataset and `extract`/`eval`
// test whether renders keep the message. Reports the watermarked images' PSNR
// and the bits the decoder reads back from the written files (the dataset-level
// BER the baseline starts from).
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "gaussian/loss.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "gaussian/util/progress.h"
#include "plugin/command.h"
#include "plugin/image_file.h"
#include "plugin/option_parser.h"
#include "watermark/decoder.h"
#include "watermark/hidden_model.h"
#include "watermark/image_encoding.h"
#include "watermark/message.h"

namespace watergs {
namespace {

namespace fs = std::filesystem;

// The PNG and JPEG files directly in `dir`, sorted by name.
std::vector<fs::path> ImageFiles(const std::string& dir) {
  if (!fs::is_directory(dir)) FailAt(dir, "not a folder");
  std::vector<fs::path> files;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    if (entry.is_regular_file() &&
        (ext == ".png" || ext == ".jpg" || ext == ".jpeg")) {
      files.push_back(entry.path());
    }
  }
  if (files.empty()) FailAt(dir, "no .png or .jpg images");
  std::sort(files.begin(), files.end());
  return files;
}

int RunEncodeImages(int argc, char** argv) {
  std::string image_path, output_path, model_path, message_text;
  OptionParser parser(
      "encode_images",
      "Watermarks every PNG/JPEG image of a folder with a HiDDeN encoder "
      "(the 'HiDDeN + 3DGS' baseline: train 3DGS on the written folder with "
      "train --image_path, then extract from its renders). Names are kept; "
      "every file is written losslessly as PNG data (also under a .jpg "
      "name, read by content).");
  parser.AddRequired("image_path", &image_path, "Folder of cover images");
  parser.AddRequired("output_path", &output_path,
                     "Folder for the watermarked images (created)");
  parser.AddRequired("model", &model_path,
                     "Weights file with an encoder (train_decoder's output)");
  parser.AddRequired("message", &message_text,
                     std::string("Message: ") + kMessageFormats);
  if (!parser.Parse(argc, argv)) return 0;
  // The default (auto) runs it on the CPU; only an explicit cuda is refused.
  if (parser.Given("device") && parser.device() == Device::kCuda) {
    Fail("encode_images: the encoder runs on the CPU (use --device cpu)");
  }
  if (SamePath(image_path, output_path)) {
    Fail("encode_images: --output_path must differ from --image_path");
  }
  const std::vector<fs::path> files = ImageFiles(image_path);
  std::unique_ptr<HiddenModel> model = LoadHiddenModel(model_path, true);
  const Bits message = ParseMessage(message_text, model->config.num_bits);
  Decoder decoder(model.get());
  fs::create_directories(output_path);
  ProgressBar bar("encode", static_cast<int64_t>(files.size()));
  double psnr = 0;
  int64_t bit_errors = 0;
  for (size_t i = 0; i < files.size(); ++i) {
    const ImageRGB cover = ReadImageFile(files[i].string());
    const std::string out =
        (fs::path(output_path) / files[i].filename()).string();
    WriteImageFile(out, EncodeImage(*model, cover, message), ".png");
    // What training will see: the written 8-bit file.
    const ImageRGB written = ReadImageFile(out);
    psnr += Psnr(written, cover) / files.size();
    const std::vector<float> logits = decoder.Logits(written);
    for (size_t b = 0; b < message.size(); ++b) {
      bit_errors += (logits[b] > 0) != bool(message[b]);
    }
    bar.Update(static_cast<int64_t>(i + 1), files[i].filename().string());
  }
  bar.Finish();
  const double ber = double(bit_errors) / (message.size() * files.size());
  std::printf(
      "encoded %zu images into %s: mean PSNR %.2f dB against the covers, "
      "BER %.2f%% read back from the written files\n",
      files.size(), output_path.c_str(), psnr, 100 * ber);
  return 0;
}

}  // namespace
}  // namespace watergs

WATERGS_COMMAND(encode_images,
                "Watermarks a folder of images with a HiDDeN encoder (the "
                "HiDDeN + 3DGS baseline)",
                watergs::RunEncodeImages);
