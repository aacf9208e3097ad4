// Tests of the PlayCanvas SOG reader and writer: round-trip error bounds of
// each attribute (16-bit log positions, 8-bit quaternions and alphas,
// 256-entry codebooks, the SH palette), deterministic bytes, the unbundled
// layout (meta.json beside its images) read the same as the bundle, 8-bit
// alphas of 0 and 255 read as finite logits, and one-line refusals of every
// malformed part: ZIP, JSON, version, fields, images, tags, indices.
#include "gaussian/formats/sog_io.h"

#include <gtest/gtest.h>
#include <unistd.h>
#include <webp/encode.h>
#include <zip.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "gaussian/formats/model_io.h"
#include "gaussian/formats/ply_io.h"
#include "gaussian/util/error.h"
#include "gaussian/util/file_util.h"
#include "tests/common/random_model.h"
#include "tests/common/refusal.h"

namespace watergs {
namespace {

using Files = std::map<std::string, std::string>;
using nlohmann::json;

const uint8_t* Bytes(const std::string& s) {
  return reinterpret_cast<const uint8_t*>(s.data());
}

// The members of a ZIP held in memory.
Files Unzip(const std::string& bundle) {
  zip_error_t error;
  zip_error_init(&error);
  zip_source_t* source =
      zip_source_buffer_create(bundle.data(), bundle.size(), 0, &error);
  zip_t* archive = zip_open_from_source(source, ZIP_RDONLY, &error);
  EXPECT_NE(archive, nullptr);
  Files files;
  for (zip_int64_t i = 0; archive && i < zip_get_num_entries(archive, 0); ++i) {
    zip_file_t* member = zip_fopen_index(archive, zip_uint64_t(i), 0);
    std::string bytes;
    char buffer[4096];
    zip_int64_t got = 0;
    while ((got = zip_fread(member, buffer, sizeof buffer)) > 0) {
      bytes.append(buffer, size_t(got));
    }
    zip_fclose(member);
    files[zip_get_name(archive, zip_uint64_t(i), 0)] = bytes;
  }
  zip_discard(archive);
  return files;
}

GaussianModel DecodeFiles(const Files& files) {
  return DecodeSogFiles(
      "test.sog", files.at("meta.json"), [&](const std::string& name) {
        const auto it = files.find(name);
        if (it == files.end()) {
          FailAt("test.sog: " + Printable(name), "file not found");
        }
        return it->second;
      });
}

// The one-line error for `files` (tests/common/refusal.h).
std::string Refusal(const Files& files) {
  return testing::Refusal("test.sog", [&] { DecodeFiles(files); });
}

std::string Webp(const std::vector<uint8_t>& rgba, int width, int height) {
  uint8_t* out = nullptr;
  const size_t size =
      WebPEncodeLosslessRGBA(rgba.data(), width, height, 4 * width, &out);
  std::string bytes(reinterpret_cast<const char*>(out), size);
  WebPFree(out);
  return bytes;
}

double Sigmoid(double x) { return 1 / (1 + std::exp(-x)); }

TEST(SogIo, RoundTripErrorsStayWithinTheFormatsSteps) {
  const GaussianModel model = RandomModel(3000, 3, 7);
  std::vector<uint32_t> order;
  const std::string bytes = EncodeSog(model, {}, &order);
  const GaussianModel back = DecodeSog("rt.sog", Bytes(bytes), bytes.size());
  ASSERT_EQ(back.size(), model.size());
  ASSERT_EQ(back.sh_degree, 3);
  ASSERT_EQ(back.CountNonFinite(), 0u);
  double sh_error = 0, sh_energy = 0, max_pos = 0, max_alpha = 0, max_dot = 0;
  double scale_error = 0, dc_error = 0;
  for (size_t t = 0; t < back.size(); ++t) {
    const size_t i = order[t];
    for (int k = 0; k < 3; ++k) {
      // 16 bits over log1p of a [-1, 1] range: a step of ~2e-5.
      max_pos = std::max(max_pos, double(std::abs(back.means[3 * t + k] -
                                                  model.means[3 * i + k])));
      scale_error +=
          std::abs(back.log_scales[3 * t + k] - model.log_scales[3 * i + k]);
      dc_error += std::abs(back.sh_dc[3 * t + k] - model.sh_dc[3 * i + k]);
    }
    max_alpha = std::max(max_alpha, std::abs(Sigmoid(back.opacity_logits[t]) -
                                             Sigmoid(model.opacity_logits[i])));
    double dot = 0, norm = 0;
    for (int k = 0; k < 4; ++k) {
      dot += back.quats[4 * t + k] * model.quats[4 * i + k];
      norm += model.quats[4 * i + k] * model.quats[4 * i + k];
    }
    max_dot = std::max(max_dot, 1 - std::abs(dot) / std::sqrt(norm));
    for (int k = 0; k < model.sh_rest_stride(); ++k) {
      const double v = model.sh_rest[i * model.sh_rest_stride() + k];
      const double d = back.sh_rest[t * model.sh_rest_stride() + k] - v;
      sh_error += d * d;
      sh_energy += v * v;
    }
  }
  EXPECT_LT(max_pos, 1e-4);
  EXPECT_LE(max_alpha, 1.0 / 255 + 1e-6);  // truncated, as splat-transform
  EXPECT_LT(max_dot, 1e-3);                // about 2 degrees at worst
  EXPECT_LT(scale_error / (3 * back.size()), 0.01);  // 256 levels over 1.0
  EXPECT_LT(dc_error / (3 * back.size()), 0.01);     // 256 levels over 2.0
  // A palette of 2048 for 3000 random SH vectors keeps most of the energy;
  // dropping the bands would lose all of it.
  EXPECT_LT(sh_error, 0.5 * sh_energy);
  EXPECT_EQ(EncodeSog(model), bytes) << "the same model gave other bytes";
}

TEST(SogIo, ReadsTheFileSplatTransformWrote) {
  // tests/data/sog: 64 Gaussians of SH degree 3 with random values
  // (source.ply) and the .sog PlayCanvas splat-transform 2.7.1 wrote of them
  // (`-g cpu -i 10`). Matched by position, every value within the format's
  // steps; measured at most: position 4.1e-5, alpha 0.0039, log-scale
  // 0.0063, SH DC 0.0065, SH rest 0.0015, quaternion |dot| >= 0.99995. A
  // convention read wrong (an SH sign or order, a colour offset, an axis, the
  // quaternion's component order) errs by 0.1 or more.
  const std::string dir = std::string(WATERGS_SOURCE_DIR) + "/tests/data/sog/";
  const GaussianModel source = ReadPly(dir + "source.ply").model;
  const GaussianModel read =
      ReadModelFile(dir + "splat_transform_2.7.1.sog").model;
  ASSERT_EQ(read.size(), 64u);
  ASSERT_EQ(read.sh_degree, 3);
  std::vector<bool> used(64, false);
  const auto sigmoid = [](double x) { return 1 / (1 + std::exp(-x)); };
  for (size_t i = 0; i < read.size(); ++i) {
    size_t j = 0;
    double nearest = INFINITY;
    for (size_t k = 0; k < source.size(); ++k) {
      double d2 = 0;
      for (int c = 0; c < 3; ++c) {
        const double d = read.means[3 * i + c] - source.means[3 * k + c];
        d2 += d * d;
      }
      if (d2 < nearest) nearest = d2, j = k;
    }
    EXPECT_FALSE(used[j]) << "two Gaussians read at one place";
    used[j] = true;
    EXPECT_LT(std::sqrt(nearest), 1e-4) << i;
    EXPECT_NEAR(sigmoid(read.opacity_logits[i]),
                sigmoid(source.opacity_logits[j]), 1 / 255.0 + 1e-4)
        << i;
    double dot = 0, norm_read = 0, norm_source = 0;
    for (int c = 0; c < 4; ++c) {
      dot += read.quats[4 * i + c] * source.quats[4 * j + c];
      norm_read += read.quats[4 * i + c] * read.quats[4 * i + c];
      norm_source += source.quats[4 * j + c] * source.quats[4 * j + c];
    }
    EXPECT_GT(std::abs(dot) / std::sqrt(norm_read * norm_source), 0.9999) << i;
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(read.log_scales[3 * i + c], source.log_scales[3 * j + c],
                  0.01)
          << i;
      EXPECT_NEAR(read.sh_dc[3 * i + c], source.sh_dc[3 * j + c], 0.01) << i;
    }
    const int stride = read.sh_rest_stride();
    for (int c = 0; c < stride; ++c) {
      EXPECT_NEAR(read.sh_rest[i * stride + c], source.sh_rest[j * stride + c],
                  0.003)
          << i << " coefficient " << c;
    }
  }
}

TEST(SogIo, UnbundledMetaReadsAsTheBundle) {
  const GaussianModel model = RandomModel(200, 1, 8);
  const std::string bundle = EncodeSog(model);
  const auto dir = std::filesystem::temp_directory_path() /
                   ("watergs_sog_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  for (const auto& [name, bytes] : Unzip(bundle)) {
    AtomicWriteFile((dir / name).string(), bytes);
  }
  const ModelData folder = ReadModelFile((dir / "meta.json").string());
  const GaussianModel zipped = DecodeSog("b.sog", Bytes(bundle), bundle.size());
  EXPECT_EQ(folder.format, GaussianFormat::kSog);
  EXPECT_EQ(folder.model.means, zipped.means);
  EXPECT_EQ(folder.model.sh_rest, zipped.sh_rest);
  EXPECT_EQ(folder.model.opacity_logits, zipped.opacity_logits);
  // A meta.json must not reach outside its folder.
  json meta = json::parse(ReadFileBytes((dir / "meta.json").string()));
  // Neither a path outside the folder nor a name that would break the
  // error's line is read.
  for (const char* name : {"../quats.webp", "quats\n.webp"}) {
    meta["quats"]["files"][0] = name;
    AtomicWriteFile((dir / "meta.json").string(), meta.dump());
    try {
      ReadModelFile((dir / "meta.json").string());
      ADD_FAILURE() << "read " << name;
    } catch (const Error& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("only files beside meta.json"), std::string::npos)
          << message;
      EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
  }
  std::filesystem::remove_all(dir);
}

TEST(SogIo, AlphasOfZeroAndOneReadAsFiniteLogits) {
  GaussianModel model = RandomModel(2, 0, 9);
  model.opacity_logits = {-1000.f, 1000.f};  // sigmoid: 0 and 1 in double
  const std::string bytes = EncodeSog(model);
  const GaussianModel back = DecodeSog("a.sog", Bytes(bytes), bytes.size());
  ASSERT_EQ(back.CountNonFinite(), 0u);
  std::vector<float> logits = back.opacity_logits;
  std::sort(logits.begin(), logits.end());
  EXPECT_EQ(logits[0], -kOpacityLogitLimit);
  EXPECT_EQ(logits[1], kOpacityLogitLimit);
}

TEST(SogIo, PositionsNearFloatsLimitEncodeAgain) {
  GaussianModel model = RandomModel(4, 0, 12);
  model.means[0] = 3e38f;  // log1p is 88.6, beyond the reader's +-88
  const std::string bytes = EncodeSog(model);
  const GaussianModel back = DecodeSog("far.sog", Bytes(bytes), bytes.size());
  ASSERT_EQ(back.CountNonFinite(), 0u);
  const std::string again = EncodeSog(back);
  EXPECT_EQ(DecodeSog("again.sog", Bytes(again), again.size()).size(), 4u);
}

TEST(SogIo, EmptyModelRoundTrips) {
  GaussianModel model;
  model.sh_degree = 0;
  const std::string bytes = EncodeSog(model);
  EXPECT_EQ(DecodeSog("e.sog", Bytes(bytes), bytes.size()).size(), 0u);
}

TEST(SogIo, RefusesBrokenArchives) {
  const std::string bundle = EncodeSog(RandomModel(50, 1, 10));
  for (const size_t keep :
       {size_t(0), size_t(10), bundle.size() / 2, bundle.size() - 10}) {
    try {
      DecodeSog("cut.sog", Bytes(bundle), keep);
      ADD_FAILURE() << "accepted a cut at " << keep;
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).rfind("cut.sog: ", 0), 0u) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
  }
  // A flipped byte inside a stored member fails its CRC.
  std::string flipped = bundle;
  flipped[bundle.size() / 2] ^= 0x20;
  EXPECT_THROW(DecodeSog("flip.sog", Bytes(flipped), flipped.size()), Error);
}

TEST(SogIo, RefusesMalformedMetaAndImages) {
  const Files good = Unzip(EncodeSog(RandomModel(40, 1, 11)));
  ASSERT_NO_THROW(DecodeFiles(good));
  auto with_meta = [&](const std::function<void(json&)>& edit) {
    Files files = good;
    json meta = json::parse(files["meta.json"]);
    edit(meta);
    files["meta.json"] = meta.dump();
    return files;
  };
  Files text = good;
  text["meta.json"] = "{\"means\": [1, 2,\x01";
  EXPECT_NE(Refusal(text).find("not JSON"), std::string::npos);
  EXPECT_NE(Refusal(with_meta([](json& m) {
              m.erase("version");
            })).find("SOG version 1"),
            std::string::npos);
  EXPECT_NE(Refusal(with_meta([](json& m) {
              m["version"] = 3;
            })).find("version 3, expected 2"),
            std::string::npos);
  EXPECT_NE(Refusal(with_meta([](json& m) {
              m.erase("scales");
            })).find("no 'scales'"),
            std::string::npos);
  EXPECT_NE(Refusal(with_meta([](json& m) {
              m["count"] = -4;
            })).find("'count' must be an integer"),
            std::string::npos);
  EXPECT_NE(Refusal(with_meta([](json& m) {
              m["count"] = 1u << 30;
            })).find("'count' must be an integer"),
            std::string::npos);
  EXPECT_NE(Refusal(with_meta([](json& m) {
              m["count"] = 100000;
            })).find("fewer than the 100000 needed"),
            std::string::npos);
  EXPECT_NE(Refusal(with_meta([](json& m) {
              m["scales"]["codebook"] = std::vector<double>(300, 0.0);
            })).find("'codebook' must be an array of 0-256"),
            std::string::npos);
  EXPECT_NE(Refusal(with_meta([](json& m) {
              m["sh0"]["codebook"] = std::vector<double>{0.5};
            })).find("-entry codebook"),
            std::string::npos);
  EXPECT_NE(Refusal(with_meta([](json& m) {
              m["shN"]["count"] = 1;
            })).find("-entry palette"),
            std::string::npos);
  EXPECT_NE(Refusal(with_meta([](json& m) {
              m["means"]["maxs"][0] = 1e3;
            })).find("beyond +-88"),
            std::string::npos);
  Files missing = good;
  missing.erase("quats.webp");
  EXPECT_NE(Refusal(missing).find("quats.webp: file not found"),
            std::string::npos);
  Files not_webp = good;
  not_webp["sh0.webp"] = "RIFF\x10\0\0\0WEBPjunk";
  EXPECT_NE(Refusal(not_webp).find("sh0.webp: not a WebP"), std::string::npos);
  Files huge = good;
  huge["scales.webp"] = Webp(std::vector<uint8_t>(4 * 4000 * 40, 0), 4000, 40);
  EXPECT_NE(Refusal(huge).find("absurd size"), std::string::npos);
  // A count no image holds is refused before the model is sized for it
  // (2^27 - 1 Gaussians of degree 1 would be 11 GB).
  EXPECT_NE(Refusal(with_meta([](json& m) {
              m["count"] = (1u << 27) - 1;
            })).find("needed"),
            std::string::npos);
  Files lossy = good;
  uint8_t* out = nullptr;
  const std::vector<uint8_t> grey(4 * 8 * 8, 128);
  const size_t lossy_size = WebPEncodeRGBA(grey.data(), 8, 8, 32, 90.f, &out);
  lossy["sh0.webp"] =
      std::string(reinterpret_cast<const char*>(out), lossy_size);
  WebPFree(out);
  EXPECT_NE(Refusal(lossy).find("sh0.webp: a lossy WebP"), std::string::npos);
  Files bad_tag = good;
  bad_tag["quats.webp"] = Webp(std::vector<uint8_t>(4 * 8 * 8, 7), 8, 8);
  EXPECT_NE(Refusal(bad_tag).find("tag 7, expected 252-255"),
            std::string::npos);
}

}  // namespace
}  // namespace watergs
