#pragma once
// Mesostructure in voxel space (conventions: kernels/meso.h): the tiling height field every
// map is built from, the limits of the maps, and the helpers the builders share. GLM only.
//
// The maps, one header each: distance_transform.h (Felzenszwalb & Huttenlocher's exact EDT),
// distance_map.h (Donnelly's map), cones.h + ddm.h (Mehra & Kumar's conservative directional
// distance map), compression.h (its two-level compression), quadrics.h (Appendix B); the
// marchers over them: march.h. Every builder validates its input and throws ArgumentError
// naming the value.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/core/error.h"
#include "dispmap/core/parallel.h"
#include "dispmap/kernels/meso.h"

namespace dispmap {

/// Limits of the maps (voxels per axis; cones).
inline constexpr int kMaxMesoSize = 4096;
inline constexpr int kMaxMesoLayers = 256;

namespace detail {
inline int wrapIndex(int i, int n) {
    const int r = i % n;
    return r < 0 ? r + n : r;
}
// Runs body(i) for i in [0, n) on `threads` threads (core/parallel.h), one index a task: the
// builders give each task a layer or a row of voxels, which only it writes.
template <class Body> void parallelRows(int n, int threads, const Body& body) {
    Parallel(threads).each(static_cast<std::size_t>(std::max(n, 0)), 1, [&](std::size_t i) { body(static_cast<int>(i)); });
}
// The largest float <= x (x >= 0): a bound stays a bound when it is stored as a float.
inline float floatBelow(double x) {
    float f = static_cast<float>(x);
    if (static_cast<double>(f) > x) f = std::nextafter(f, 0.0f);
    return f;
}
inline void checkMesoSize(const char* what, int width, int height, int layers) {
    if (width < 2 || height < 2 || width > kMaxMesoSize || height > kMaxMesoSize)
        throw ArgumentError(std::string(what) + ": size " + std::to_string(width) + " x " + std::to_string(height) +
                            " is out of range (2 .. " + std::to_string(kMaxMesoSize) + " per axis)");
    if (layers < 2 || layers > kMaxMesoLayers)
        throw ArgumentError(std::string(what) + ": " + std::to_string(layers) + " layers is out of range (2 .. " +
                            std::to_string(kMaxMesoLayers) + ")");
}
} // namespace detail

/// A tiling height field in voxel units: heights at the texel grid points (i, j), x fastest,
/// each in [0, layers]; the surface is their periodic bilinear interpolant (kernels/meso.h).
struct MesoHeightField {
    int width = 0, height = 0, layers = 0;
    std::vector<float> h;

    float at(int x, int y) const {
        return h[static_cast<std::size_t>(detail::wrapIndex(y, height)) * static_cast<std::size_t>(width) +
                 static_cast<std::size_t>(detail::wrapIndex(x, width))];
    }
    /// Corner heights of column (i, j) in dmBilerp's order (h00, h10, h11, h01), wrapped.
    glm::vec4 cell(int i, int j) const { return {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)}; }
    float maxHeight() const { return h.empty() ? 0.0f : *std::max_element(h.begin(), h.end()); }
};

/// A height field of width x height heights (voxels, each in [0, layers]). ArgumentError for
/// sizes out of range, a wrong count, non-finite or out-of-range heights.
inline MesoHeightField mesoHeightField(int width, int height, int layers, std::vector<float> heights) {
    detail::checkMesoSize("height field", width, height, layers);
    if (heights.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height))
        throw ArgumentError("height field: " + std::to_string(heights.size()) + " heights for " + std::to_string(width) +
                            " x " + std::to_string(height) + " texels");
    for (std::size_t i = 0; i < heights.size(); ++i)
        if (!std::isfinite(heights[i]) || heights[i] < 0.0f || heights[i] > static_cast<float>(layers))
            throw ArgumentError("height field: height " + std::to_string(heights[i]) + " at texel (" +
                                std::to_string(i % static_cast<std::size_t>(width)) + ", " +
                                std::to_string(i / static_cast<std::size_t>(width)) + ") is not finite or not in [0, " +
                                std::to_string(layers) + "]");
    MesoHeightField f;
    f.width = width;
    f.height = height;
    f.layers = layers;
    f.h = std::move(heights);
    return f;
}

/// From image values v in [0, 1] (column x, row y as stored): height = depth v, depth in
/// (0, layers] voxels (default: the whole slab).
template <class Image> MesoHeightField mesoHeightFieldFromImage(const Image& img, int layers, double depth = -1) {
    if (img.width < 1 || img.height < 1 || img.values.empty()) throw ArgumentError("height field: the image is empty");
    if (depth < 0) depth = layers;
    if (!std::isfinite(depth) || depth <= 0 || depth > layers)
        throw ArgumentError("height field: depth " + std::to_string(depth) + " is not in (0, " + std::to_string(layers) + "]");
    std::vector<float> h(img.values.size());
    for (std::size_t i = 0; i < h.size(); ++i) {
        const float v = img.values[i];
        if (!std::isfinite(v)) throw ArgumentError("height field: image value at " + std::to_string(i) + " is not finite");
        h[i] = static_cast<float>(std::clamp(static_cast<double>(v), 0.0, 1.0) * depth);
    }
    return mesoHeightField(img.width, img.height, layers, std::move(h));
}

} // namespace dispmap
