// benchmarks/resident_raster.h without the CUDA backend: nothing to time.
#include "benchmarks/resident_raster.h"

namespace watergs::bench {

ResidentRasterTiming TimeResidentRaster(const GaussianModel&,
                                        const RenderCamera&,
                                        const RenderOptions&, int) {
  return {};
}

}  // namespace watergs::bench
