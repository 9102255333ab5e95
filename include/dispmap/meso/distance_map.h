#pragma once
// DistanceMap: Donnelly's isotropic map (GPU Gems 2 ch. 8), Euclidean distances sampled at
// (i, j, k + 1/2), read with trilinear filtering: not conservative, as in the chapter. GLM only.
#include "dispmap/meso/distance_transform.h"
#include "dispmap/meso/height_field.h"

namespace dispmap {

/// Donnelly's distance map: for every sample (i, j, k + 1/2), i < width, j < height, k < layers,
/// the exact Euclidean distance (voxels) to the column model of the surface sampled
/// `subsamples` times per texel: the vertical half-lines {(x, y, z) : z <= H(x, y)} at the
/// points (i + a/S, j + b/S), periodic (S = 1: the height samples themselves). It approximates
/// the distance to the bilinear surface from above (overestimating it by up to ~0.7/S voxels
/// between the half-lines) and is read trilinearly, as in the chapter: no bound, which is
/// what its marchers' errors show. Samples inside the solid hold minus the distance to the
/// air's column model ({z >= H}, the same transform): with the chapter's unsigned map the
/// trilinear zero set lies on the layer centre below the surface (a stop up to a layer too
/// deep, found by the first test of this map); signed, it lies within interpolation error of
/// the surface and sphere tracing stops there (dist <= eps).
struct DistanceMap {
    int width = 0, height = 0, layers = 0, subsamples = 1;
    std::vector<float> d; // [k][j][i]
    float at(int i, int j, int k) const {
        return d[(static_cast<std::size_t>(k) * static_cast<std::size_t>(height) +
                  static_cast<std::size_t>(detail::wrapIndex(j, height))) *
                     static_cast<std::size_t>(width) +
                 static_cast<std::size_t>(detail::wrapIndex(i, width))];
    }
    std::size_t bytes() const { return d.size() * sizeof(float); }
};

/// Per layer: g(x, y) = (max(0, z - H(x, y)) S)^2 on the S-times finer grid, its 2D transform
/// (O(S^2 width height layers)), the samples at the texel grid points, divided by S. Layers on
/// `threads` threads (core/parallel.h; the same map for every count).
inline DistanceMap buildDistanceMap(const MesoHeightField& hf, int subsamples = 4, int threads = 0) {
    detail::checkMesoSize("distance map", hf.width, hf.height, hf.layers);
    checkThreads(threads, "distance map");
    if (subsamples < 1 || subsamples > 16) throw ArgumentError("distance map: subsamples " + std::to_string(subsamples) + " not in 1..16");
    DistanceMap m;
    m.width = hf.width;
    m.height = hf.height;
    m.layers = hf.layers;
    m.subsamples = subsamples;
    const int S = subsamples, fw = hf.width * S, fh = hf.height * S;
    const std::size_t slice = static_cast<std::size_t>(hf.width) * static_cast<std::size_t>(hf.height);
    std::vector<double> H(static_cast<std::size_t>(fw) * static_cast<std::size_t>(fh));
    for (int y = 0; y < fh; ++y)
        for (int x = 0; x < fw; ++x)
            H[static_cast<std::size_t>(y) * static_cast<std::size_t>(fw) + static_cast<std::size_t>(x)] =
                kern::dmBilerp(glm::dvec4(hf.cell(x / S, y / S)), glm::dvec2(double(x % S) / S, double(y % S) / S));
    m.d.resize(slice * static_cast<std::size_t>(hf.layers));
    detail::parallelRows(hf.layers, threads, [&](int k) {
        const double z = k + 0.5;
        std::vector<double> g(H.size()), air(H.size());
        for (std::size_t i = 0; i < g.size(); ++i) {
            const double above = std::max(0.0, z - H[i]) * S, below = std::max(0.0, H[i] - z) * S;
            g[i] = above * above;
            air[i] = below * below;
        }
        squaredDistanceTransform2D(g.data(), fw, fh);
        squaredDistanceTransform2D(air.data(), fw, fh);
        for (int j = 0; j < hf.height; ++j)
            for (int i = 0; i < hf.width; ++i) {
                const std::size_t at = static_cast<std::size_t>(j) * static_cast<std::size_t>(S) * static_cast<std::size_t>(fw) + static_cast<std::size_t>(i) * static_cast<std::size_t>(S);
                m.d[static_cast<std::size_t>(k) * slice + static_cast<std::size_t>(j * hf.width + i)] =
                    static_cast<float>(g[at] > 0 ? std::sqrt(g[at]) / S : -std::sqrt(air[at]) / S);
            }
    });
    return m;
}

} // namespace dispmap
