// libFuzzer target: trainer/embedder checkpoints (gaussian/checkpoint.h). The
// trailing checksum is recomputed so that mutations reach the parser. A
// checkpoint that reads must hold a state a resume can use: a consistent,
// finite model and an active SH degree within the model's.
#include <cmath>

#include "fuzz/fuzz_support.h"
#include "gaussian/checkpoint.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace watergs;
  const std::vector<uint8_t> bytes =
      fuzz::WithValidChecksum(data, size, [](const uint8_t* p, size_t n) {
        return watergs::Fnv1a64(static_cast<const void*>(p), n);
      });
  const std::string path =
      fuzz::WriteScratchFile("checkpoint.bin", bytes.data(), bytes.size());
  try {
    const TrainingCheckpoint checkpoint = ReadCheckpoint(path);
    const GaussianModel& m = checkpoint.model;
    const size_t n = m.size();
    if (m.sh_degree < 0 || m.sh_degree > 3 || m.means.size() != 3 * n ||
        m.log_scales.size() != 3 * n || m.quats.size() != 4 * n ||
        m.sh_dc.size() != 3 * n || m.sh_rest.size() != n * m.sh_rest_stride()) {
      fuzz::Finding("checkpoint read with an inconsistent model");
    }
    // Resuming uses these as they are: SH evaluation up to the active
    // degree, parameters straight into the optimiser.
    if (checkpoint.active_sh_degree < 0 ||
        checkpoint.active_sh_degree > m.sh_degree) {
      fuzz::Finding("checkpoint read with active SH degree " +
                    std::to_string(checkpoint.active_sh_degree) +
                    " outside the model's 0-" + std::to_string(m.sh_degree));
    }
    for (const auto* array : {&m.means, &m.log_scales, &m.quats,
                              &m.opacity_logits, &m.sh_dc, &m.sh_rest}) {
      for (const float v : *array) {
        if (!std::isfinite(v)) fuzz::Finding("checkpoint read with NaN/Inf");
      }
    }
  } catch (const Error& e) {
    fuzz::ExpectOneLineError(e, path);
  }
  return 0;
}
