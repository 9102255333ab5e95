#pragma once
// Images as plain data: heights in [0, 1] (HeightImage) and 8-bit RGBA pixels (RgbaImage),
// and bilinear sampling of heights at OBJ texture coordinates. Reading and writing them as
// PNG files is io/png.h (libpng); this header needs only the standard library.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "dispmap/core/error.h"

namespace dispmap {

/// Largest width or height of a height image, read or written.
inline constexpr int kMaxHeightImageSize = 16384;

/// A greyscale image of heights: in [0, 1] from integer samples, as stored from float ones (io/image_files.h).
struct HeightImage {
    int width = 0, height = 0;
    /// Row by row, width * height values; row 0 is the top row of the file.
    std::vector<float> values;

    /// The value at column x, row y (row 0 at the top); x, y must be inside the image.
    float at(int x, int y) const {
        return values[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                      static_cast<std::size_t>(x)];
    }
};

/// Height images placed in UV space: one image covering [0, 1]^2 (key 0, udim false), or a
/// UDIM set whose image with key 1001 + u + 10 v covers [u, u + 1] x [v, v + 1] (udim true).
struct HeightMaps {
    std::map<int, std::shared_ptr<const HeightImage>> images;
    bool udim = false;
};

/// An 8-bit RGBA image (e.g. a rendered frame or a normal map).
struct RgbaImage {
    int width = 0, height = 0;
    /// Row by row, 4 bytes (R, G, B, A) per pixel; row 0 is the top row of the file.
    std::vector<std::uint8_t> rgba;
};

/// Bilinear sample of img at OBJ texture coordinates (s, t): s runs left to right, t bottom
/// to top, so t = 0 is the BOTTOM row of the image (the last row of values) and t = 1 the
/// top. Texel (x, y) has its centre at s = (x + 0.5) / width, t = 1 - (y + 0.5) / height;
/// the result interpolates the four texels whose centres surround (s, t). Beyond the outer
/// centres, wrap = false clamps to the edge texels and wrap = true repeats the image with
/// period 1 in s and t. Throws ArgumentError for an empty image or non-finite (s, t).
inline double sampleHeightBilinear(const HeightImage& img, double s, double t, bool wrap) {
    if (img.width < 1 || img.height < 1 ||
        img.values.size() != static_cast<std::size_t>(img.width) * static_cast<std::size_t>(img.height))
        throw ArgumentError("sampleHeightBilinear: empty or inconsistent image (" +
                            std::to_string(img.width) + " x " + std::to_string(img.height) + ", " +
                            std::to_string(img.values.size()) + " values)");
    if (!std::isfinite(s) || !std::isfinite(t))
        throw ArgumentError("sampleHeightBilinear: texture coordinate (" + std::to_string(s) + ", " +
                            std::to_string(t) + ") is not finite");
    // One axis: the two texel indices around coordinate c (in texel units, centres at
    // integers) and the weight of the second.
    struct Axis {
        int i0, i1;
        double f;
    };
    const auto axis = [wrap](double c, int n) {
        if (wrap) {
            c -= std::floor(c / n) * n; // into [0, n]
        } else {
            c = std::clamp(c, 0.0, static_cast<double>(n - 1));
        }
        const double fl = std::floor(c);
        int i0 = static_cast<int>(fl);
        int i1 = i0 + 1;
        if (wrap) {
            i0 = (i0 % n + n) % n;
            i1 = (i1 % n + n) % n;
        } else {
            i0 = std::min(i0, n - 1);
            i1 = std::min(i1, n - 1);
        }
        return Axis{i0, i1, c - fl};
    };
    // s = (x + 0.5) / w  ->  x = s w - 0.5;   t = 1 - (y + 0.5) / h  ->  y = (1 - t) h - 0.5.
    const Axis ax = axis(s * img.width - 0.5, img.width);
    const Axis ay = axis((1.0 - t) * img.height - 0.5, img.height);
    const auto texel = [&img](int x, int y) { return static_cast<double>(img.at(x, y)); };
    const double row0 = (1.0 - ax.f) * texel(ax.i0, ay.i0) + ax.f * texel(ax.i1, ay.i0);
    const double row1 = (1.0 - ax.f) * texel(ax.i0, ay.i1) + ax.f * texel(ax.i1, ay.i1);
    return (1.0 - ay.f) * row0 + ay.f * row1;
}

} // namespace dispmap
