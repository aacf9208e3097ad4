// Clustering for the codebook formats (SOG): an optimal 1D quantiser
// for scalar codebooks and Lloyd's k-means over vectors for palettes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

namespace watergs {

// k-means in 1D, solved exactly: `values` (any order, finite) -> `codebook`
// of at most k ascending centroids (fewer when there are fewer distinct
// values) with the least sum of squared errors, and labels[i], the index of
// the centroid nearest values[i]. Beyond 65536 distinct values the values
// are binned at 1/65536 of their range first. k in [1, 65536]; a k whose
// table would exceed 2^24 entries (k > 256 on many values) falls back to
// Lloyd's algorithm from the k quantiles, which can leave a sparse tail
// under one entry (a 256-entry log-scale codebook did: 21 dB renders).
void Quantize1d(const std::vector<float>& values, int k,
                std::vector<float>* codebook, std::vector<uint32_t>* labels);

// Lloyd's k-means over n points of `dim` floats (row-major): k centroids
// (k <= n; k = n gives every point its own) after `iterations` rounds, each
// point's label its nearest centroid (exact, via a k-d tree). Seeds are k
// distinct points picked with `seed`, so a run is reproducible; a centroid
// left without points takes the point farthest from its own centroid.
// `on_round`, if set, is called after each round with the rounds done.
void KMeans(const std::vector<float>& points, int dim, size_t k, int iterations,
            uint64_t seed, std::vector<float>* centroids,
            std::vector<uint32_t>* labels,
            const std::function<void(int)>& on_round = nullptr);

}  // namespace watergs
