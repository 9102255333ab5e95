#pragma once
// A displacement map placed on a mesh through its UVs, as a source for the tile fit:
// D = offset + scale * (h(uv) - midLevel), one image or a UDIM set, UVs linear or smooth
// (surface/uv_map.h), each sample point-sampled or prefiltered over its footprint.
//
// Prefiltering. The fit asks for D at the s x s sub-patch centres of a tile (s = 2^k). When
// the map has more texels than that, a point sample aliases: it keeps whichever texel the
// centre happens to hit. With a filter each sample integrates the map over its footprint,
// the parallelogram uv + du a + dv b (du, dv: the UV derivatives at the centre):
//  * Box:  a, b in [-h/2, h/2], h = 1/s, uniform weight (the texels of one sub-patch);
//  * Tent: a, b in [-h, h], weight (1 - |a|/h)(1 - |b|/h) (the linear B-spline: what a
//          sample shares with its neighbours is weighted down, so less aliasing survives).
// The integral is a midpoint rule over the bilinear reconstruction of the map with about one
// tap per texel the footprint spans (the span rounded; at most maxTaps per axis): where a
// sample spans less than 1.5 texels the box is the point sample, and the tent two taps.
// `dispmap maps --table` measures error against the full-resolution map and build time for
// the three.
//
// UDIM. The tile of a face is the one holding the UV of its centre; every corner of the face
// must lie in that tile (within half a texel), else the face spans two tiles: an error. A
// face whose tile the set lacks is an error naming the face and the tiles there are.
// Overlapping UVs (two faces covering one texel) are an error unless allowed: a displacement
// map holds one height per texel. (Not checked with wrap, where a layout may repeat on
// purpose.)
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "dispmap/core/error.h"
#include "dispmap/core/height_image.h"
#include "dispmap/surface/tile_builder.h"
#include "dispmap/surface/uv_map.h"

namespace dispmap {

enum class MapFilter { Point, Box, Tent };

inline const char* toString(MapFilter f) { return f == MapFilter::Point ? "point" : f == MapFilter::Box ? "box" : "tent"; }

/// The filter named `name` (point, box, tent), or none.
inline std::optional<MapFilter> parseMapFilter(std::string_view name) {
    if (name == "point") return MapFilter::Point;
    if (name == "box") return MapFilter::Box;
    if (name == "tent") return MapFilter::Tent;
    return std::nullopt;
}

struct MapSourceOptions {
    double scale = 1.0, offset = 0.0;
    double midLevel = 0.0;   ///< the height that means no displacement
    bool wrap = false;       ///< one image only: repeat it outside [0, 1] (else a UV outside is an error)
    MapFilter filter = MapFilter::Point;
    int maxTaps = 16;        ///< filter taps per axis at most (box; the tent takes twice as many)
    bool allowOverlap = false; ///< do not refuse faces that overlap in UV space
};

namespace detail {

/// Checks a height image's shape; throws ArgumentError naming `what`.
inline void checkHeightImage(const HeightImage* img, const std::string& what) {
    if (!img || img->width < 1 || img->height < 1 ||
        img->values.size() != static_cast<std::size_t>(img->width) * static_cast<std::size_t>(img->height))
        throw ArgumentError(what + " is empty or malformed");
}

/// The UDIM numbers of a set, "1001, 1002": for messages.
inline std::string udimList(const HeightMaps& maps) {
    std::string s;
    for (const auto& [n, img] : maps.images) s += (s.empty() ? "" : ", ") + std::to_string(n);
    return s;
}

/// The unit UV square of UDIM tile `udim` (0: [0, 1]^2).
inline glm::dvec2 udimOrigin(int udim) {
    return udim == 0 ? glm::dvec2(0.0) : glm::dvec2((udim - 1001) % 10, (udim - 1001) / 10);
}

} // namespace detail

/// Calls visit(x, y, ptexFace, u, v) for every texel centre of a w x h image of the unit UV
/// square of UDIM tile `udim` (0: [0, 1]^2; row 0 at the top, t = 1) that a ptex face with
/// faceTiles[face] == udim covers, with the face's (u, v) there. Each face is cut into
/// steps x steps cells of its parameters (a quad 2 steps x 2 steps: its edges are twice a
/// sub-face's, so both sides of an edge a quad shares with a sub-face sample it at the same
/// points) whose UV images are split into two triangles; a
/// texel centre in a triangle gets (u, v) by the triangle's interpolation, then `newton`
/// Newton steps on the UV map make uv(face, u, v) equal the texel centre. inset > 0 takes only
/// centres more than `inset` (in barycentric terms) inside a triangle; inset = 0 takes those
/// on the edges too, so a centre on an edge two faces share is visited for both. `shift`
/// moves the square (by whole periods, for a map that wraps).
template <typename Visit>
void rasterizeUvs(const UvMap& uvs, const std::vector<int>& faceTiles, int udim, int w, int h, int steps, double inset, int newton,
                  Visit&& visit, glm::dvec2 shift = glm::dvec2(0.0)) {
    const glm::dvec2 origin = detail::udimOrigin(udim) + shift;
    const glm::dvec2 size(w, h);
    // texel coordinates: x = (s - origin) w - 1/2, y = (1 - (t - origin)) h - 1/2
    const auto texel = [&](glm::dvec2 uv) { return glm::dvec2((uv.x - origin.x) * w, (1.0 - (uv.y - origin.y)) * h) - 0.5; };
    std::vector<glm::dvec2> grid;
    for (int t = 0; t < uvs.ptexFaceCount(); ++t) {
        if (faceTiles[static_cast<std::size_t>(t)] != udim) continue;
        const int n = uvs.isSubFace(t) ? steps : 2 * steps;
        grid.resize(static_cast<std::size_t>((n + 1) * (n + 1)));
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i)
                grid[static_cast<std::size_t>(j * (n + 1) + i)] = texel(uvs(t, static_cast<double>(i) / n, static_cast<double>(j) / n));
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i)
                for (int corner = 0; corner < 2; ++corner) {
                    // corners (parameter, texel position) of one triangle of the cell
                    const glm::ivec2 c[3] = {corner == 0 ? glm::ivec2(i, j) : glm::ivec2(i + 1, j + 1), glm::ivec2(i + 1, j),
                                             glm::ivec2(i, j + 1)};
                    glm::dvec2 p[3], q[3];
                    for (int m = 0; m < 3; ++m) {
                        p[m] = grid[static_cast<std::size_t>(c[m].y * (n + 1) + c[m].x)];
                        q[m] = glm::dvec2(c[m]) / static_cast<double>(n);
                    }
                    const double area = (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[2].x - p[0].x) * (p[1].y - p[0].y);
                    if (!(std::abs(area) > 1e-14)) continue;
                    // the texel range, clamped in double first (UVs far outside would overflow int)
                    const auto first = [](double a, int extent) { return static_cast<int>(std::clamp(std::ceil(a - 1e-9), 0.0, static_cast<double>(extent))); };
                    const auto last = [](double a, int extent) { return static_cast<int>(std::clamp(std::floor(a + 1e-9), -1.0, extent - 1.0)); };
                    const int x0 = first(std::min({p[0].x, p[1].x, p[2].x}), w), x1 = last(std::max({p[0].x, p[1].x, p[2].x}), w);
                    const int y0 = first(std::min({p[0].y, p[1].y, p[2].y}), h), y1 = last(std::max({p[0].y, p[1].y, p[2].y}), h);
                    for (int y = y0; y <= y1; ++y)
                        for (int x = x0; x <= x1; ++x) {
                            const glm::dvec2 z(x, y);
                            const double w0 = ((p[1].x - z.x) * (p[2].y - z.y) - (p[2].x - z.x) * (p[1].y - z.y)) / area;
                            const double w1 = ((p[2].x - z.x) * (p[0].y - z.y) - (p[0].x - z.x) * (p[2].y - z.y)) / area;
                            const double w2 = 1.0 - w0 - w1;
                            const double lo = inset > 0 ? inset : -1e-12;
                            if (inset > 0 ? (w0 <= lo || w1 <= lo || w2 <= lo) : (w0 < lo || w1 < lo || w2 < lo)) continue;
                            glm::dvec2 uv = w0 * q[0] + w1 * q[1] + w2 * q[2];
                            const glm::dvec2 target = origin + glm::dvec2((x + 0.5) / size.x, 1.0 - (y + 0.5) / size.y);
                            for (int step = 0; step < newton; ++step) {
                                const UvSample s = uvs.evaluate(t, uv.x, uv.y);
                                const double det = s.du.x * s.dv.y - s.dv.x * s.du.y;
                                if (!(std::abs(det) > 1e-300)) break;
                                const glm::dvec2 r = target - s.uv;
                                uv += glm::dvec2(r.x * s.dv.y - s.dv.x * r.y, s.du.x * r.y - r.x * s.du.y) / det;
                                uv = glm::clamp(uv, 0.0, 1.0);
                            }
                            visit(x, y, t, uv.x, uv.y);
                        }
                }
    }
}

namespace detail {

/// The first two ptex faces that cover one texel centre of a res x res raster of some UDIM
/// tile's square (strictly inside both: a shared edge is no overlap), and that tile; {-1, -1,
/// 0} if none.
inline std::array<int, 3> firstUvOverlap(const UvMap& uvs, const std::vector<int>& faceTiles, int res, int steps) {
    std::vector<int> tiles = faceTiles;
    std::sort(tiles.begin(), tiles.end());
    tiles.erase(std::unique(tiles.begin(), tiles.end()), tiles.end());
    std::vector<int> owner(static_cast<std::size_t>(res) * static_cast<std::size_t>(res));
    for (int udim : tiles) {
        std::fill(owner.begin(), owner.end(), 0);
        std::array<int, 3> found{-1, -1, 0};
        rasterizeUvs(uvs, faceTiles, udim, res, res, steps, 1e-9, 0, [&](int x, int y, int t, double, double) {
            int& o = owner[static_cast<std::size_t>(y) * static_cast<std::size_t>(res) + static_cast<std::size_t>(x)];
            if (o != 0 && o != t + 1 && found[0] < 0) found = {o - 1, t, udim};
            o = t + 1;
        });
        if (found[0] >= 0) return found;
    }
    return {-1, -1, 0};
}

} // namespace detail

/// The UDIM tile number (1001 + u + 10 v) of every ptex face under `uvs`, or 0 for every
/// face when `udim` is false. Throws ArgumentError for a face whose corners lie in two
/// tiles (more than `margin` outside the tile of its centre) or outside 1001..1100.
inline std::vector<int> udimTiles(const UvMap& uvs, bool udim, double margin) {
    std::vector<int> out(static_cast<std::size_t>(uvs.ptexFaceCount()), 0);
    if (!udim) return out;
    for (int t = 0; t < uvs.ptexFaceCount(); ++t) {
        const glm::dvec2 c = uvs(t, 0.5, 0.5);
        const double tu = std::floor(c.x), tv = std::floor(c.y);
        const auto where = [&] {
            return uvs.meshName() + ": face " + std::to_string(uvs.baseFace(t) + 1) + " (UV centre (" + std::to_string(c.x) +
                   ", " + std::to_string(c.y) + "))";
        };
        if (tu < 0 || tu > 9 || tv < 0 || tv > 9) throw ArgumentError(where() + " lies outside the UDIM tiles 1001..1100");
        const int tile = 1001 + static_cast<int>(tu) + 10 * static_cast<int>(tv);
        for (const glm::dvec2 p : {glm::dvec2(0, 0), glm::dvec2(1, 0), glm::dvec2(1, 1), glm::dvec2(0, 1)}) {
            const glm::dvec2 q = uvs(t, p.x, p.y);
            if (q.x < tu - margin || q.x > tu + 1 + margin || q.y < tv - margin || q.y > tv + 1 + margin)
                throw ArgumentError(where() + " spans UDIM tiles: its centre is in " + std::to_string(tile) +
                                    ", its corner UV (" + std::to_string(q.x) + ", " + std::to_string(q.y) +
                                    ") is not; split the face's UVs at the tile border");
        }
        out[static_cast<std::size_t>(t)] = tile;
    }
    return out;
}

/// The displacement source of a UV-mapped height map (one image or a UDIM set) on the mesh
/// of `uvs`, sampling the ptex faces' tiles of sizes `k` (one log2 size per ptex face; may be
/// empty for MapFilter::Point). Throws ArgumentError for an empty or malformed image, non-finite
/// scale/offset/mid-level, k of the wrong length, a UV outside the image (one image, no
/// wrap: more than half a texel), a face spanning UDIM tiles or reading a missing one, and
/// overlapping faces (unless allowed).
inline DisplacementFunction mapSource(std::shared_ptr<const UvMap> uvs, const HeightMaps& maps, std::vector<int> k,
                                      const MapSourceOptions& o) {
    if (!uvs) throw ArgumentError("mapSource: no UV map");
    const std::string& name = uvs->meshName();
    if (maps.images.empty()) throw ArgumentError("height map: no image given");
    for (const auto& [n, img] : maps.images)
        detail::checkHeightImage(img.get(), maps.udim ? "height map UDIM tile " + std::to_string(n) : std::string("height image"));
    if (!maps.udim && (maps.images.size() != 1 || maps.images.begin()->first != 0))
        throw ArgumentError("height map: one image (key 0) unless it is a UDIM set");
    if (!std::isfinite(o.scale) || !std::isfinite(o.offset) || !std::isfinite(o.midLevel))
        throw ArgumentError("height scale, offset and mid-level must be finite");
    if (o.filter != MapFilter::Point && k.size() != static_cast<std::size_t>(uvs->ptexFaceCount()))
        throw ArgumentError("mapSource: " + std::to_string(k.size()) + " tile sizes for " +
                            std::to_string(uvs->ptexFaceCount()) + " ptex faces");
    if (o.filter != MapFilter::Point)
        for (std::size_t t = 0; t < k.size(); ++t)
            if (k[t] < kMinTileLog2 || k[t] > kMaxTileLog2)
                throw ArgumentError("mapSource: tile size 2^" + std::to_string(k[t]) + " of ptex face " + std::to_string(t) +
                                    " out of range [2^" + std::to_string(kMinTileLog2) + ", 2^" + std::to_string(kMaxTileLog2) + "]");
    if (o.maxTaps < 1 || o.maxTaps > 256) throw ArgumentError("mapSource: maxTaps must be in [1, 256]");
    if (maps.udim && o.wrap) throw ArgumentError("height map: wrapping does not apply to a UDIM set");
    int finest = 1;
    for (const auto& [n, img] : maps.images) finest = std::max({finest, img->width, img->height});
    const double halfTexel = 0.5 / finest;
    std::vector<int> tiles = udimTiles(*uvs, maps.udim, halfTexel);
    for (int t = 0; t < uvs->ptexFaceCount(); ++t) {
        const int tile = tiles[static_cast<std::size_t>(t)];
        if (maps.udim && !maps.images.count(tile))
            throw ArgumentError(name + ": face " + std::to_string(uvs->baseFace(t) + 1) + " lies in UDIM tile " +
                                std::to_string(tile) + ", which the set does not have (it has " + detail::udimList(maps) + ")");
        if (!maps.udim && !o.wrap) {
            const HeightImage& img = *maps.images.begin()->second;
            const double sx = 0.5 / img.width, sy = 0.5 / img.height;
            for (const glm::dvec2 p : {glm::dvec2(0, 0), glm::dvec2(1, 0), glm::dvec2(1, 1), glm::dvec2(0, 1)}) {
                const glm::dvec2 q = (*uvs)(t, p.x, p.y);
                // Within half a texel outside [0, 1] the clamped lookup reads the border texel anyway
                // (layouts that touch the border overshoot by rounding); further out needs wrap.
                if (q.x < -sx || q.x > 1.0 + sx || q.y < -sy || q.y > 1.0 + sy)
                    throw ArgumentError(name + ": face " + std::to_string(uvs->baseFace(t) + 1) + " has texture coordinate (" +
                                        std::to_string(q.x) + ", " + std::to_string(q.y) +
                                        ") outside the image; enable wrapping or fix the mesh");
            }
        }
    }
    if (!o.allowOverlap && !o.wrap) {
        const auto [a, b, udim] = detail::firstUvOverlap(*uvs, tiles, std::min(finest, 2048), uvs->smooth() ? 4 : 1);
        if (a >= 0)
            throw ArgumentError(name + ": faces " + std::to_string(uvs->baseFace(a) + 1) + " and " +
                                std::to_string(uvs->baseFace(b) + 1) + " overlap in UV space" +
                                (maps.udim ? " (UDIM tile " + std::to_string(udim) + ")" : std::string()) +
                                ": a displacement map holds one height per texel (allow overlapping UVs to use it anyway)");
    }
    struct State {
        std::shared_ptr<const UvMap> uvs;
        std::vector<std::pair<std::shared_ptr<const HeightImage>, glm::dvec2>> faceImage; // image and tile origin per ptex face
        std::vector<int> k;
        MapSourceOptions o;
    };
    auto st = std::make_shared<State>();
    st->uvs = uvs;
    st->k = std::move(k);
    st->o = o;
    st->faceImage.resize(tiles.size());
    for (std::size_t t = 0; t < tiles.size(); ++t) {
        const int tile = tiles[t];
        st->faceImage[t] = {maps.images.at(tile), detail::udimOrigin(tile)};
    }
    return [st](int face, double u, double v) {
        const MapSourceOptions& opt = st->o;
        const auto& [img, origin] = st->faceImage[static_cast<std::size_t>(face)];
        const UvSample s = st->uvs->evaluate(face, u, v);
        const auto h = [&](glm::dvec2 uv) { return sampleHeightBilinear(*img, uv.x - origin.x, uv.y - origin.y, opt.wrap); };
        double height = 0.0;
        if (opt.filter == MapFilter::Point) {
            height = h(s.uv);
        } else {
            const double step = 1.0 / (1 << st->k[static_cast<std::size_t>(face)]);
            // texels spanned by the sub-patch along u and v
            const auto span = [&](glm::dvec2 d) { return std::hypot(d.x * img->width, d.y * img->height) * step; };
            const bool tent = opt.filter == MapFilter::Tent;
            // about one tap per texel: a sample spanning less than 1.5 texels is a point sample
            const int na = std::clamp(static_cast<int>(std::lround(span(s.du))), 1, opt.maxTaps) * (tent ? 2 : 1);
            const int nb = std::clamp(static_cast<int>(std::lround(span(s.dv))), 1, opt.maxTaps) * (tent ? 2 : 1);
            const double reach = tent ? step : 0.5 * step; // half-width of the support
            double sum = 0.0, weights = 0.0;
            for (int j = 0; j < nb; ++j) {
                const double b = reach * (2.0 * (j + 0.5) / nb - 1.0);
                const double wb = tent ? 1.0 - std::abs(b) / step : 1.0;
                for (int i = 0; i < na; ++i) {
                    const double a = reach * (2.0 * (i + 0.5) / na - 1.0);
                    const double w = wb * (tent ? 1.0 - std::abs(a) / step : 1.0);
                    sum += w * h(s.uv + a * s.du + b * s.dv);
                    weights += w;
                }
            }
            height = sum / weights;
        }
        return opt.offset + opt.scale * (height - opt.midLevel);
    };
}

/// One UV-mapped height image as a displacement source: D = offset + scale * h(uv), UVs
/// linear over each face (a sub-face: corner, edge midpoints, centroid), point-sampled, UV
/// overlaps allowed: mapSource with its defaults. Throws ArgumentError as mapSource, and
/// for a mesh without texture coordinates.
inline DisplacementFunction imageSource(const ControlMesh& mesh, std::shared_ptr<const HeightImage> image, double scale,
                                        double offset, bool wrap = false) {
    MapSourceOptions o;
    o.scale = scale;
    o.offset = offset;
    o.wrap = wrap;
    o.allowOverlap = true;
    HeightMaps maps;
    maps.images[0] = std::move(image);
    return mapSource(std::make_shared<const UvMap>(mesh, UvInterpolation::Linear), maps, {}, o);
}

/// The tiles written back into UV space: a w x h image of UDIM tile `udim` (0: [0, 1]^2)
/// whose texels covered by a face hold the height h with D = offset + scale * (h - midLevel),
/// D evaluated from the tiles' finest level at the face's (u, v) there (rasterizeUvs, 8 x 8
/// cells a face and 3 Newton steps); `covered` (if given) receives 1 per texel a face covers.
/// Texels no face covers hold midLevel. With `wrap` (one image, udim 0) the parts of faces
/// outside [0, 1]^2 land where a wrapping lookup reads them (the square and its 8 neighbours
/// are rasterised). For round-trip checks and for other tools. Throws ArgumentError for a
/// size out of range, scale 0, or a tile count other than the UV map's ptex faces.
inline HeightImage tilesToMap(const UvMap& uvs, const TileSet& tiles, int udim, int w, int h, double scale, double offset,
                              double midLevel, std::vector<std::uint8_t>* covered = nullptr, bool wrap = false) {
    if (w < 1 || h < 1 || w > kMaxHeightImageSize || h > kMaxHeightImageSize)
        throw ArgumentError("map size " + std::to_string(w) + " x " + std::to_string(h) + " out of range [1, " +
                            std::to_string(kMaxHeightImageSize) + "]");
    if (!(std::abs(scale) > 0.0) || !std::isfinite(scale) || !std::isfinite(offset) || !std::isfinite(midLevel))
        throw ArgumentError("map: scale must be finite and not 0, offset and mid-level finite");
    if (tiles.tileCount() != uvs.ptexFaceCount())
        throw ArgumentError("map: " + std::to_string(tiles.tileCount()) + " tiles for a mesh of " +
                            std::to_string(uvs.ptexFaceCount()) + " ptex faces");
    const std::vector<int> faceTiles = udimTiles(uvs, udim != 0, 1.0);
    HeightImage img;
    img.width = w;
    img.height = h;
    img.values.assign(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), static_cast<float>(midLevel));
    if (covered) covered->assign(img.values.size(), 0);
    if (wrap && udim != 0) throw ArgumentError("map: wrapping does not apply to a UDIM tile");
    const auto write = [&](int x, int y, int t, double u, double v) {
        const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
        img.values[i] = static_cast<float>((tiles.evaluate<double>(t, 0, glm::dvec2(u, v)) - offset) / scale + midLevel);
        if (covered) (*covered)[i] = 1;
    };
    for (int dy = wrap ? -1 : 0; dy <= (wrap ? 1 : 0); ++dy)
        for (int dx = wrap ? -1 : 0; dx <= (wrap ? 1 : 0); ++dx) rasterizeUvs(uvs, faceTiles, udim, w, h, 8, 0.0, 3, write, glm::dvec2(dx, dy));
    return img;
}

/// Per-ptex-face tile sizes from the map's texel density: the smallest k with 2^k at least
/// the texels the face spans along u and along v (measured at 3 x 3 points), clamped to
/// [kMin, kMax]. On a mesh with non-quad faces the sub-faces of non-quads take kMax - 1 and
/// the quads at the ends of an edge shared with a non-quad take kMax (the builder's
/// T-junction rule, as mixedTileSizes). Throws ArgumentError for sizes out of range.
inline std::vector<int> texelTileSizes(const ControlMesh& mesh, const UvMap& uvs, const HeightMaps& maps, int kMin, int kMax) {
    std::vector<int> out = uniformTileSizes(mesh, kMax); // checks kMax, and sub-faces take kMax - 1
    if (kMin < kMinTileLog2 || kMin > kMax)
        throw ArgumentError("smallest tile size 2^" + std::to_string(kMin) + " out of range [2^" + std::to_string(kMinTileLog2) +
                            ", 2^" + std::to_string(kMax) + "]");
    const std::vector<int> tiles = udimTiles(uvs, maps.udim, 1.0); // (the source checks the margins)
    const std::vector<char> pinned = quadsPinnedByNonQuads(mesh);
    const Far::TopologyLevel& L = mesh.base();
    for (int f = 0; f < L.GetNumFaces(); ++f) {
        if (L.GetFaceVertices(f).size() != 4 || pinned[static_cast<std::size_t>(f)]) continue;
        const int t = mesh.ptex().GetFaceId(f);
        const auto it = maps.images.find(tiles[static_cast<std::size_t>(t)]);
        if (it == maps.images.end() || !it->second) continue; // mapSource names the missing tile
        const HeightImage& img = *it->second;
        double texels = 1.0;
        for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i) {
                const UvSample s = uvs.evaluate(t, 0.5 * i, 0.5 * j);
                texels = std::max({texels, std::hypot(s.du.x * img.width, s.du.y * img.height),
                                   std::hypot(s.dv.x * img.width, s.dv.y * img.height)});
            }
        const int k = static_cast<int>(std::ceil(std::log2(texels) - 1e-9));
        out[static_cast<std::size_t>(t)] = std::clamp(k, kMin, kMax);
    }
    return out;
}

/// Per-ptex-face tile sizes from a fit-error bound (coarsestTileWithin, the bake's --adaptive
/// rule): each quad's D sampled through `options` (filter, scale, mid-level...) at 2^kMax x
/// 2^kMax sub-patch centres, then the smallest k in [kMin, kMax] whose box-filtered samples
/// reproduce those within `tolerance` (in D's units) by bilinear interpolation. Flat or smooth
/// stretches of the map get small tiles, detail keeps 2^kMax. Non-quads' sub-faces take
/// kMax - 1 and the quads pinned by them kMax (the builder's T-junction rule, as
/// texelTileSizes). Then neighbours are balanced to one level apart at most (raising the
/// smaller), since a tile's overlap ring comes from its neighbours' mips. Throws
/// ArgumentError for sizes out of range or a tolerance that is not finite and > 0; propagates
/// what mapSource throws.
inline std::vector<int> errorTileSizes(const ControlMesh& mesh, std::shared_ptr<const UvMap> uvs, const HeightMaps& maps, int kMin,
                                       int kMax, double tolerance, const MapSourceOptions& options = {}) {
    std::vector<int> out = uniformTileSizes(mesh, kMax); // checks kMax, and sub-faces take kMax - 1
    if (kMin < kMinTileLog2 || kMin > kMax)
        throw ArgumentError("smallest tile size 2^" + std::to_string(kMin) + " out of range [2^" + std::to_string(kMinTileLog2) +
                            ", 2^" + std::to_string(kMax) + "]");
    if (!(tolerance > 0.0) || !std::isfinite(tolerance))
        throw ArgumentError("tile size tolerance " + std::to_string(tolerance) + " must be finite and > 0");
    const DisplacementFunction src = mapSource(std::move(uvs), maps, out, options);
    const std::vector<char> pinned = quadsPinnedByNonQuads(mesh);
    const Far::TopologyLevel& L = mesh.base();
    const int s = 1 << kMax;
    std::vector<double> fine;
    for (int f = 0; f < L.GetNumFaces(); ++f) {
        if (L.GetFaceVertices(f).size() != 4 || pinned[static_cast<std::size_t>(f)]) continue;
        const int t = mesh.ptex().GetFaceId(f);
        fine.resize(static_cast<std::size_t>(s) * static_cast<std::size_t>(s)); // the last face's were replaced by coarser ones
        for (int j = 0; j < s; ++j)
            for (int i = 0; i < s; ++i) fine[static_cast<std::size_t>(j * s + i)] = src(t, (i + 0.5) / s, (j + 0.5) / s);
        out[static_cast<std::size_t>(t)] = coarsestTileWithin(fine, kMax, tolerance, kMin);
    }
    // Balance: neighbours differ by at most one level (in texel spacing: a sub-face's k + 1 is a
    // quad's k). A tile's overlap ring comes from its neighbours' mips at its own resolution;
    // a 2 x 2 tile next to a 64 x 64 one would take the detail's coarse mean into its whole
    // interior, which is not within the tolerance of its own data.
    const TileTopology topo(mesh);
    for (bool changed = true; changed;) {
        changed = false;
        for (int t = 0; t < topo.tileCount(); ++t)
            for (int e = 0; e < 4; ++e)
                for (const TileTopology::Link& l : topo.links(t, e)) {
                    const int mine = out[static_cast<std::size_t>(t)] + topo.scale(t);
                    const int theirs = out[static_cast<std::size_t>(l.tile)] + topo.scale(l.tile);
                    if (mine < theirs - 1) {
                        out[static_cast<std::size_t>(t)] = theirs - 1 - topo.scale(t);
                        changed = true;
                    }
                }
    }
    return out;
}

} // namespace dispmap
