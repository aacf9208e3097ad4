// The "CONCAT + 3DGS" baseline of the paper (Sec. 3, "Concatenating
// Watermarks with Attributes"; Sec. 5): an explicit encoder writes the
// message into the SH coefficients of a trained 3DGS model. One small MLP,
// shared by all Gaussians, maps a Gaussian's chosen SH coefficients h_i and
// the message m (as +-1) to an offset: h_i' = h_i + E(h_i, m). Unlike WATER-GS
// the Gaussians are not fine-tuned; only E's weights are trained, per scene,
// through the rasterizer and the frozen decoder with a random message each
// iteration (a message-conditioned encoder, as HiDDeN's), on the loss
// (1 - β) L1 + β D-SSIM + γ BCE(m, D(render)). Applying E once with the
// owner's message gives the watermarked model; every other attribute stays
// bit-identical.
#pragma once

#include <array>
#include <cstdint>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "gaussian/gaussian_model.h"
#include "gaussian/loss.h"
#include "gaussian/rasterizer.h"
#include "gaussian/trainer.h"
#include "watermark/bit_decoder.h"
#include "watermark/message.h"
#include "watermark/nn_layers.h"

namespace watergs {

// Which SH groups the encoder reads and offsets.
struct ShTarget {
  // f_dc: the degree-0 coefficients (3 per Gaussian).
  bool dc = true;
  // f_rest: the higher coefficients (model.sh_rest_stride() per Gaussian).
  bool rest = true;
  // Coefficients per Gaussian for a model of `sh_degree`.
  int NumCoeffs(int sh_degree) const;
};

// Parses "f_dc", "f_rest", or "sh" / "f_dc,f_rest" (both); throws Error.
ShTarget ParseShTarget(const std::string& text);

// The chosen coefficients of Gaussian i of `model` into `row`
// (target.NumCoeffs values: f_dc's 3 first, then f_rest in the model's
// layout), and back: `offset` added to them in `model`.
void PackShRow(const GaussianModel& model, const ShTarget& target, size_t i,
               float* row);
void AddShRow(const ShTarget& target, const float* offset, size_t i,
              GaussianModel* model);

// Weights of the MLP E as views (row-major): w1 [hidden, coeffs + bits]
// whose first `coeffs` columns read h_i and the rest the message, b1
// [hidden], w2 [coeffs, hidden], b2 [coeffs].
template <typename T>
struct ConcatMlpWeights {
  int coeffs = 0, bits = 0, hidden = 0;
  std::span<T> w1, b1, w2, b2;
};

// inputs (n x coeffs, one Gaussian per row), signs (bits values +-1) ->
// offsets (n x coeffs) = w2 relu(w1 [h; m] + b1) + b2; `hidden` (n x hidden)
// keeps the ReLU outputs for the backward pass. The message's part of w1 is
// the same for all Gaussians, so it is folded into the bias once.
template <typename T>
void ConcatMlpForward(const ConcatMlpWeights<const T>& w,
                      std::span<const T> inputs, std::span<const T> signs,
                      std::vector<T>* offsets, std::vector<T>* hidden);

// Adds dLoss/dweights into `grads` (same shapes as w) for doffsets (n x
// coeffs), given the forward pass's inputs, signs and hidden.
template <typename T>
void ConcatMlpBackward(const ConcatMlpWeights<const T>& w,
                       std::span<const T> inputs, std::span<const T> signs,
                       std::span<const T> hidden, std::span<const T> doffsets,
                       const ConcatMlpWeights<T>& grads);

// The encoder E: the MLP's parameters (NetworkAdam trains them), forward on
// a model's Gaussians and backward from the rasterizer's SH gradients.
class ConcatEncoder {
 public:
  // For `num_bits` messages on models of `sh_degree`; w1 and b1 get
  // Linear's (PyTorch's) initialisation, w2 and b2 zero so that E starts at
  // 0 (h' = h). Throws Error for a target with no coefficient at that degree
  // or a non-positive width.
  ConcatEncoder(const ShTarget& target, int sh_degree, int num_bits, int hidden,
                uint32_t seed);

  // h' = h + E(h, m) on the target groups of `model` (Error unless `model`
  // is finite, has this encoder's SH degree and the message its length, and
  // every result is finite); every other array is copied bit-identically.
  GaussianModel Apply(const GaussianModel& model, const Bits& message) const;
  // As above into `out` (not `model`), reusing its storage.
  void Apply(const GaussianModel& model, const Bits& message,
             GaussianModel* out) const;
  // Adds dLoss/dweights to the parameters' grad for out = Apply(model,
  // message), from dLoss/d(out)'s sh_dc / sh_rest (the rasterizer's
  // gradients, not compact). Only Gaussians marked visible (all when
  // grads.visible is empty) contribute; their hidden layer is recomputed, so
  // nothing per Gaussian is kept between Apply and Backward.
  void Backward(const GaussianModel& model, const Bits& message,
                const GaussianGradients& grads);

  // w1, b1, w2, b2.
  std::vector<Parameter*> Parameters();
  const ShTarget& target() const { return target_; }
  int num_bits() const { return num_bits_; }
  int sh_degree() const { return sh_degree_; }

 private:
  ConcatMlpWeights<const float> Weights() const;
  // Error unless `model`'s SH degree and `message`'s length fit this
  // encoder.
  void CheckFits(const GaussianModel& model, const Bits& message) const;

  ShTarget target_;
  int sh_degree_, num_bits_, coeffs_, hidden_;
  // Hold the parameters (w1 = fc1.weight, ...); the batched arithmetic over
  // all Gaussians is ConcatMlpForward / Backward, not Linear's per-sample
  // loops.
  Linear fc1_, fc2_;
  // Backward's gathered rows (reused).
  std::vector<float> rows_inputs_, rows_hidden_, rows_offsets_, rows_doffsets_;
};

struct ConcatTrainOptions {
  // Training iterations of the encoder.
  int64_t iterations = 2000;
  // Weight of the message loss.
  double gamma = 0.3;
  // Weight of D-SSIM in the image loss.
  double beta = 0.2;
  // Adam step size for the encoder's weights.
  double learning_rate = 1e-3;
  // Side of the random square crop rendered per iteration (clamped to the
  // frame); 0 renders whole frames.
  int crop_size = 128;
  // Seeds views, crops and the random messages.
  uint64_t seed = 0;
  // Colour behind the Gaussians.
  std::array<float, 3> background = {0.f, 0.f, 0.f};
  // Draw a progress bar on stderr.
  bool show_progress = false;
};

// Figures of one training iteration.
struct ConcatStepStats {
  int64_t iteration = 0;
  // Image loss of the crop, BCE of its decoded message, total loss.
  LossTerms image;
  double bce = 0, total = 0;
  int bit_errors = 0;
};

// Trains a ConcatEncoder on `model`'s views through the rasterizer (public
// interface only) and the frozen decoder.
class ConcatEncoderTrainer {
 public:
  // `views`, `model`, `decoder`, `rasterizer` and `encoder` outlive the
  // trainer; `train_views` index into `views`. Error if the decoder's length
  // differs from the encoder's, the model is empty or not finite.
  ConcatEncoderTrainer(const ConcatTrainOptions& options,
                       const TrainingViews& views,
                       std::vector<size_t> train_views,
                       const GaussianModel& model, BitDecoder* decoder,
                       Rasterizer* rasterizer, ConcatEncoder* encoder);
  // One iteration with a fresh random message; Error on a non-finite loss.
  ConcatStepStats Step();
  int64_t iteration() const { return iteration_; }

 private:
  ConcatTrainOptions options_;
  const TrainingViews& views_;
  std::vector<size_t> train_views_;
  const GaussianModel& model_;
  BitDecoder* decoder_;
  Rasterizer* rasterizer_;
  ConcatEncoder* encoder_;
  NetworkAdam adam_;
  TrainingLoss loss_;
  std::mt19937_64 rng_;
  int64_t iteration_ = 0;
  // Reused per-iteration buffers.
  GaussianModel encoded_;
  ImageRGB render_, truth_crop_, grad_image_;
  GaussianGradients grads_;
};

// Runs options.iterations steps (progress bar with the loss and BER when
// options.show_progress); returns the last step's figures.
ConcatStepStats TrainConcatEncoder(const ConcatTrainOptions& options,
                                   const TrainingViews& views,
                                   const std::vector<size_t>& train_views,
                                   const GaussianModel& model,
                                   BitDecoder* decoder, Rasterizer* rasterizer,
                                   ConcatEncoder* encoder);

}  // namespace watergs
