#pragma once
// MesoAlbedo: an RGBA8 image over one tile: the colour of a mesostructure, or its normal map
// (tangent space, normalMapFromHeights below; kern::dmNormalMapTangent reads a texel). It
// repeats with the height field: at texture coordinate (s, t) in tiles, the image's texel
// (s w + shift.x, t h + shift.y) with w x h its size, wrapping; texel (x, y) sits on the height
// field's sample ((x - shift.x) W / w, (y - shift.y) H / h), so a colour image of the field's size
// (shift 0) colours each height sample with its own pixel. The shift, in texels of level 0, is
// applied where the image is read (kern::dmMesoImage), not by resampling the image: a scene
// whose field averages blocks of its height image reads its colour images a fraction of a
// texel on (detail::mesoImageShift, scene/meso.h), and resampling them once blurred them. It has box-filtered mip levels for the footprint of a pixel (a normal
// map's levels average the encoded vectors, which the reader scales back to unit length).
// Sampled by kern::dmMesoImage (kernels/meso_march.h) on the CPU (sampleMesoAlbedo) and in the
// MesoRenderer's fragment shader, from one array of 32-bit words:
//   word 0                  the level count n
//   words 1 + 4 l .. +3     level l: offset of its first texel word, width, height, 0
//   words 1 + 4 n, 2 + 4 n  the shift (x, y), float bits
//   then the texels         level by level, rows from y = 0, x fastest; one RGBA8 texel a word,
//                           red in the lowest byte (kern::dmUnpackRgba8)
// Level l + 1 is the 2 x 2 box average of level l (rounded to nearest), floor(w / 2) x
// floor(h / 2) texels (at least 1: an odd last row or column is dropped), down to 1 x 1.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/core/error.h"
#include "dispmap/core/height_image.h"

namespace dispmap {

/// Largest side of an albedo image (texels): a 4096^2 image and its levels take 85 MiB.
inline constexpr int kMaxMesoAlbedoSize = 4096;

/// Largest |scale| of a normal map's x and y (kern::dmNormalMapTangent): at 100 a texel one
/// 8-bit step off flat already leans 68 degrees from the normal, so larger scales only
/// magnify rounding.
inline constexpr double kMaxNormalScale = 100.0;

struct MesoAlbedo {
    std::vector<std::uint32_t> words; ///< the layout of the header

    int levels() const { return words.empty() ? 0 : static_cast<int>(words[0]); }
    int width(int level = 0) const { return static_cast<int>(words[static_cast<std::size_t>(2 + 4 * level)]); }
    int height(int level = 0) const { return static_cast<int>(words[static_cast<std::size_t>(3 + 4 * level)]); }
    /// Where level 0 is read, in its texels, added to (s w, t h) (see the header).
    glm::vec2 shift() const {
        const std::size_t at = static_cast<std::size_t>(1 + 4 * levels());
        return {std::bit_cast<float>(words[at]), std::bit_cast<float>(words[at + 1])};
    }
    /// Texel (x, y) of a level (in range), packed.
    std::uint32_t texel(int level, int x, int y) const {
        return words[words[static_cast<std::size_t>(1 + 4 * level)] + static_cast<std::size_t>(y) * static_cast<std::size_t>(width(level)) +
                     static_cast<std::size_t>(x)];
    }
    std::size_t bytes() const { return 4 * words.size(); }
};

/// Why `a`'s words do not hold an image as mesoAlbedo lays them out (the reason), or "": 1 to 32
/// levels of 1 .. kMaxMesoAlbedoSize texels a side, each level's texels after the header and
/// within the words, a finite shift within the image's size. What kern::dmMesoImage reads
/// without checking; sampleMesoAlbedo and the renderer ask first.
inline std::string mesoAlbedoProblem(const MesoAlbedo& a) {
    const std::vector<std::uint32_t>& w = a.words;
    const std::size_t levels = w.empty() ? 0 : w[0];
    if (levels < 1 || levels > 32) return "its level count " + std::to_string(levels) + " is not in 1 .. 32";
    const std::size_t header = 3 + 4 * levels;
    if (w.size() < header) return "its " + std::to_string(w.size()) + " words do not hold the header of " + std::to_string(levels) + " levels";
    for (std::size_t l = 0; l < levels; ++l) {
        const std::uint64_t width = w[2 + 4 * l], height = w[3 + 4 * l], first = w[1 + 4 * l];
        if (width < 1 || height < 1 || width > kMaxMesoAlbedoSize || height > kMaxMesoAlbedoSize)
            return "level " + std::to_string(l) + " is " + std::to_string(width) + " x " + std::to_string(height) + " texels";
        if (first < header || first + width * height > w.size())
            return "level " + std::to_string(l) + "'s texels do not lie within its words after the header";
    }
    const glm::vec2 s = a.shift();
    if (!(std::abs(s.x) <= float(w[2])) || !(std::abs(s.y) <= float(w[3]))) return "its shift is not finite or beyond its size";
    return "";
}

/// The albedo of a width x height RGBA8 image (rows from the top of the image, which is t = 0:
/// the rows of a height image, io/png.h), with `mips` levels below it or none, read `shift`
/// texels of it on (see the header). ArgumentError for a size outside 1..kMaxMesoAlbedoSize,
/// too few bytes, or a shift that is not finite or beyond the image's size.
inline MesoAlbedo mesoAlbedo(int width, int height, const std::vector<std::uint8_t>& rgba, bool mips = true, glm::vec2 shift = glm::vec2(0.0f)) {
    if (width < 1 || height < 1 || width > kMaxMesoAlbedoSize || height > kMaxMesoAlbedoSize)
        throw ArgumentError("mesostructure albedo: image size " + std::to_string(width) + " x " + std::to_string(height) +
                            " out of range (1 .. " + std::to_string(kMaxMesoAlbedoSize) + ")");
    if (!(std::abs(shift.x) <= float(width)) || !(std::abs(shift.y) <= float(height)))
        throw ArgumentError("mesostructure albedo: a shift of (" + std::to_string(shift.x) + ", " + std::to_string(shift.y) +
                            ") texels is not finite or beyond the image's size");
    const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    if (rgba.size() < 4 * n)
        throw ArgumentError("mesostructure albedo: " + std::to_string(rgba.size()) + " bytes for " + std::to_string(width) + " x " +
                            std::to_string(height) + " RGBA texels");
    std::vector<glm::ivec2> sizes{{width, height}};
    while (mips && (sizes.back().x > 1 || sizes.back().y > 1)) sizes.push_back(glm::max(sizes.back() / 2, glm::ivec2(1)));
    MesoAlbedo a;
    std::size_t total = 3 + 4 * sizes.size();
    for (const glm::ivec2 s : sizes) total += static_cast<std::size_t>(s.x) * static_cast<std::size_t>(s.y);
    a.words.assign(total, 0u);
    a.words[0] = static_cast<std::uint32_t>(sizes.size());
    a.words[1 + 4 * sizes.size()] = std::bit_cast<std::uint32_t>(shift.x + 0.0f); // + 0: no -0
    a.words[2 + 4 * sizes.size()] = std::bit_cast<std::uint32_t>(shift.y + 0.0f);
    std::size_t at = 3 + 4 * sizes.size();
    for (std::size_t l = 0; l < sizes.size(); ++l) {
        a.words[1 + 4 * l] = static_cast<std::uint32_t>(at);
        a.words[2 + 4 * l] = static_cast<std::uint32_t>(sizes[l].x);
        a.words[3 + 4 * l] = static_cast<std::uint32_t>(sizes[l].y);
        at += static_cast<std::size_t>(sizes[l].x) * static_cast<std::size_t>(sizes[l].y);
    }
    const auto put = [&](int level, int x, int y, const unsigned c[4]) {
        a.words[a.words[static_cast<std::size_t>(1 + 4 * level)] + static_cast<std::size_t>(y) * static_cast<std::size_t>(sizes[static_cast<std::size_t>(level)].x) +
                static_cast<std::size_t>(x)] = c[0] | (c[1] << 8) | (c[2] << 16) | (c[3] << 24);
    };
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const std::size_t i = 4 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x));
            const unsigned c[4] = {rgba[i], rgba[i + 1], rgba[i + 2], rgba[i + 3]};
            put(0, x, y, c);
        }
    for (int l = 1; l < static_cast<int>(sizes.size()); ++l) {
        const glm::ivec2 s = sizes[static_cast<std::size_t>(l)], p = sizes[static_cast<std::size_t>(l - 1)];
        for (int y = 0; y < s.y; ++y)
            for (int x = 0; x < s.x; ++x) {
                unsigned c[4] = {0, 0, 0, 0};
                // The 2 x 2 parents (a parent side of 1 is counted twice).
                for (int dy = 0; dy < 2; ++dy)
                    for (int dx = 0; dx < 2; ++dx) {
                        const std::uint32_t w = a.texel(l - 1, std::min(2 * x + dx, p.x - 1), std::min(2 * y + dy, p.y - 1));
                        for (int k = 0; k < 4; ++k) c[k] += (w >> (8 * k)) & 255u;
                    }
                for (unsigned& v : c) v = (v + 2) / 4;
                put(l, x, y, c);
            }
    }
    return a;
}

/// A tangent-space normal map of a height image over one tile (RGBA8, rows as the image's,
/// for mesoAlbedo): the surface z = slope v(s, t), v the image's values, s and t in tiles and
/// z in tile widths (slope: the world height of one unit of v over the world width of a tile), its
/// normal (-slope dv/ds, -slope dv/dt, 1) normalised, the derivatives central differences of
/// the wrapped image at each texel. Encoded as OpenGL and glTF do: (x, y, z) -> (r, g, b) =
/// 255 (n + 1) / 2 rounded, with y towards the image's top (green up: decode with greenT = -1,
/// kern::dmNormalMapTangent); alpha 255. ArgumentError for an empty image, a size beyond
/// kMaxMesoAlbedoSize, or a slope or value that is not finite.
inline std::vector<std::uint8_t> normalMapFromHeights(const HeightImage& image, double slope) {
    const int w = image.width, h = image.height;
    if (w < 1 || h < 1 || w > kMaxMesoAlbedoSize || h > kMaxMesoAlbedoSize ||
        image.values.size() != static_cast<std::size_t>(w) * static_cast<std::size_t>(h))
        throw ArgumentError("normal map: height image of " + std::to_string(w) + " x " + std::to_string(h) + " texels (1 .. " +
                            std::to_string(kMaxMesoAlbedoSize) + " a side, with its values)");
    if (!std::isfinite(slope)) throw ArgumentError("normal map: the slope is not finite");
    for (const float v : image.values)
        if (!std::isfinite(v)) throw ArgumentError("normal map: the height image has a value that is not finite");
    std::vector<std::uint8_t> rgba(4 * image.values.size());
    const auto byte = [](double c) { return static_cast<std::uint8_t>(std::lround(std::clamp(127.5 * (c + 1.0), 0.0, 255.0))); };
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double ds = 0.5 * w * (double(image.at((x + 1) % w, y)) - double(image.at((x + w - 1) % w, y)));
            const double dt = 0.5 * h * (double(image.at(x, (y + 1) % h)) - double(image.at(x, (y + h - 1) % h)));
            const glm::dvec3 n = glm::normalize(glm::dvec3(-slope * ds, -slope * dt, 1.0));
            const std::size_t i = 4 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x));
            rgba[i] = byte(n.x);
            rgba[i + 1] = byte(-n.y); // green up: towards t = 0
            rgba[i + 2] = byte(n.z);
            rgba[i + 3] = 255;
        }
    return rgba;
}

} // namespace dispmap
