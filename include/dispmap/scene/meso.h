#pragma once
// Mesostructure scene files (JSON), rendered by `dispmap render` with the fragment-shader
// marcher (backend_vulkan MesoRenderer): a plane or any surface tiled with a height-field
// mesostructure.
//
//   {"mesostructure": {"height": "bricks.png", "size": 64, "layers": 16, "depth": 14,
//                      "cones": "4x1", "block": 4,          (or "function": "grating")
//                      "albedo": "bricks_colour.png", "normals": "height",
//                      "normalScale": 1, "normalGreen": "up"},
//    "camera": {"eye": [0.3, -1.2, 0.7], "target": [0, 0, 0], "up": [0, 0, 1], "fov": 45},
//    "light": [0.4, 0.3, 0.8], "resolution": [320, 240], "tile": 0.5, "slab": 0.06, "checker": 8,
//    "effects": {"technique": "ddm", "quadrics": true, "iterations": 128, "exitRule": 1,
//                "eps": -1, "linear": 32, "binary": 6, "shadows": false, "mips": true,
//                "silhouettes": false, "bentRays": false},
//    "base": {"mesh": "spot.obj", "isolation": 6, "displacement": {...},
//             "placement": "uv", "repeat": [8, 8], "uv": "mesh", "tessellation": 8}}
//
// Without "base" the mesostructure tiles the plane z = 0 every `tile` world units (the camera
// above it). With "base" it lies on that surface: "mesh", "isolation", "endCaps" and "displacement" as in
// a surface scene (scene/scene.h; no displacement: the Catmull-Clark limit surface itself,
// else the displaced surface, so coarse detail is tessellated and fine detail marched in one
// draw), tessellated uniformly with `tessellation` segments a face edge (1..64), placed by the
// mesh's UVs ("uv", interpolated by the rule "uv": surface/uv_map.h) or per ptex face
// ("face"), `repeat` tiles per UV unit or per face (a number or [s, t]); `slab` is the depth
// in world units below the surface (surface/frame_mesh.h, FrameMesh). "albedo": a colour
// image (PNG, RGBA8) over one tile (meso/albedo.h), sampled at each hit trilinearly over its
// mips ("mips": false: level 0 only, bilinear); none: a checker of period "checker" voxels
// (0: plain). "normals": a tangent-space normal map (PNG, RGBA8) over one tile, filtered like
// the albedo, whose normal shades instead of the height field's ("normalScale" multiplies its
// x and y, "normalGreen" "up" as OpenGL and glTF or "down" as DirectX); or "height": the
// normal map of the height image at its full resolution (normalMapFromHeights; the function's
// field without an image), so that a coarse marched field is shaded with the image's fine
// slopes: white's depth (slab depth / layers) over the tile's width (`tile` on the plane, the
// base's mean tile width on a base).
//
// Non-height-field detail: "mesh": a closed OBJ mesh (beads, rings, chain mail) in place of
// "height" / "function", voxelised into size x size x layers voxels (meso/solid.h) and marched
// by the DDM with exact triangles (technique "ddm" only; shaded by its corners' normals, no
// "depth" or "normals"). "meshTile": {"corner": [x, y, z], "size": s} puts the mesh's point
// `corner` at the tile's corner on the floor, s mesh units a tile, so the mesh may cross the
// tile's sides (chain mail: a ring through the next tile's); without it the mesh's bounding
// box is fitted to the tile.
//
// Several mesostructures: on a base, "mesostructure" may be an array of such objects, each with
// a "material" (an OBJ usemtl name of the base mesh; at most one entry without it covers the
// faces no other claims). The scene's keys are shared; an entry may give its own "repeat" and
// "slab". mesoSceneParts lists the entries, and buildMesoSceneBase groups the base's triangles
// by them (FrameMesh::groups).
//
// Effects, and only those: the maps the technique reads are the only maps built (a relief
// scene builds no distance map and no DDM; shadow cones only with "shadows"), and the
// technique's marcher is the only one compiled into the pipeline (specialisation constants).
// Every key is optional; unknown keys, bad values and missing files are ArgumentError /
// FileError naming the scene and the key.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "dispmap/io/png.h"
#include "dispmap/meso/march.h"
#include "dispmap/scene/scene.h"
#include "dispmap/scene/surface.h"
#include "dispmap/surface/frame_mesh.h"
#include "dispmap/surface/tessellator.h"

namespace dispmap {

struct MesoSceneDesc {
    std::string name;
    std::string heightImage;        ///< image path (resolved against the scene's folder); empty: the function
    std::string mesh;               ///< "mesh": a closed OBJ mesh, non-height-field detail (meso/solid.h); empty: a height field
    std::optional<MesoSolidTile> meshTile; ///< "meshTile": where the mesh lies in the tile; none: its bounding box fitted
    std::string function = "grating";
    std::string albedoImage;        ///< colour image path (resolved); empty: the checker
    std::string normalsImage;       ///< normal map path (resolved); empty: none, or from the heights
    bool normalsFromHeight = false; ///< "normals": "height"
    double normalScale = 1;         ///< "normalScale"
    bool normalGreenUp = true;      ///< "normalGreen": "up" (true) or "down"
    bool albedoMips = true;
    int size = 64, layers = 16;     ///< texels per side after a box filter (0: the image's), voxel layers
    double depth = -1;              ///< voxels of white (default: 7/8 of the layers)
    ConeSet cones{4, 1, false, false};
    int block = 4;
    glm::dvec3 eye{0.35, -1.3, 0.75}, target{0.0, 0.0, 0.0}, light{0.4, 0.3, 0.8};
    double fov = 45, tile = 0.5, slab = 0.06;
    double checker = 8; ///< the albedo's checker period, voxels (0: none)
    int width = 320, height = 240;
    glm::dvec3 up{0.0, 0.0, 1.0};
    MesoTechnique technique;
    bool shadows = false;
    /// "effects.silhouettes": the detail's own silhouettes on the base (needs "base"; the
    /// base's frames then carry its curvature, FrameMeshOptions::shape).
    bool silhouettes = false;
    /// "effects.bentRays": the view ray bent by the base's curvature (the DDM, relief mapping or
    /// POM on a height field, on a "base" only; MesoRenderOptions::bentRays).
    bool bentRays = false;
    /// The base surface ("base"): a surface scene's mesh, isolation and displacement (no
    /// camera, lights or effects of its own); none: the plane.
    std::optional<Scene> base;
    FrameMeshOptions placement;
    UvInterpolation uvRule = UvInterpolation::Mesh;
    double tessellation = 8; ///< uniform factor, segments a base-face edge
    /// Several mesostructures ("mesostructure" as an array, on a base): each is a whole
    /// description, the scene's keys shared and its own mesostructure keys. This one is entry 0.
    std::string material;         ///< "material": the OBJ material (usemtl) whose faces it covers; "": the faces no other claims
    int part = 0;                 ///< its index in the array (0 for a single object)
    std::string key = "mesostructure"; ///< its key in messages ("mesostructure[2]" in an array)
    std::vector<MesoSceneDesc> others; ///< entry 0 only: the array's entries 1, 2, ...
};

/// The scene's mesostructures: `s` (without its `others`) and then each of its `others`, in
/// the order of the scene file's array (buildMesoSceneBase groups the base's triangles in
/// that order).
inline std::vector<MesoSceneDesc> mesoSceneParts(const MesoSceneDesc& s) {
    std::vector<MesoSceneDesc> parts{s};
    parts[0].others.clear();
    parts.insert(parts.end(), s.others.begin(), s.others.end());
    return parts;
}

/// Most mesostructures in one scene: each has its own maps on the GPU and its own pipeline.
inline constexpr std::size_t kMaxMesoParts = 16;

/// Largest step counts of a mesostructure scene's marchers ("effects"): the iteration cap of
/// the distance map and DDM marchers (4 times the 1024 of the table's DDM rows), relief / POM
/// linear steps (kMaxMesoLinearSteps, meso/march.h), and bisections (float has a 24-bit
/// mantissa: more halve nothing). Every pixel may run them all on the GPU: a typo (1e9) would
/// hang it.
inline constexpr int kMaxMesoIterations = 4096;
inline constexpr int kMaxMesoBinarySteps = 32;
/// Largest memory the maps of one mesostructure may take while they are built
/// (mesoBuildBytes): the dense DDM (4 bytes per voxel and cone) is built whole before it is
/// compressed, and a 4096^2 x 256 field would need 17 GB per cone. 4 GiB fits the machines
/// dispmap runs on beside everything else.
inline constexpr std::uint64_t kMaxMesoBuildBytes = std::uint64_t{4} << 30;

/// The peak memory of buildMesoMaps for a width x height x layers field and these options,
/// estimated from the sizes alone (from above: the compressed DDM's atlas counted as large as
/// the dense map, plus its grid): the dense and compressed DDM, the distance map with its per-layer transforms
/// on as many threads as o.threads allows (at most one per layer), heights and quadrics.
inline std::uint64_t mesoBuildBytes(int width, int height, int layers, const MesoMapOptions& o) {
    const std::uint64_t texels = static_cast<std::uint64_t>(std::max(width, 0)) * static_cast<std::uint64_t>(std::max(height, 0));
    const std::uint64_t voxels = texels * static_cast<std::uint64_t>(std::max(layers, 0));
    const std::uint64_t S = static_cast<std::uint64_t>(std::clamp(o.distanceSubsamples, 1, 16));
    std::uint64_t bytes = 2 * 4 * texels; // the field, and its copy in the maps
    const std::uint64_t running = static_cast<std::uint64_t>(std::clamp(o.threads == 0 ? allCores() : o.threads, 1, std::max(layers, 1)));
    if (o.distance) bytes += 4 * voxels + 8 * S * S * texels * (1 + 2 * running); // map; fine heights; 2 transforms a running layer
    // Dense + compressed: the atlas at most as big as the dense map, plus a grid word a block.
    const std::uint64_t b = static_cast<std::uint64_t>(std::clamp(o.block, 1, 32));
    if (o.ddm) bytes += (2 * 4 * voxels + 4 * voxels / (b * b * b) + 4) * static_cast<std::uint64_t>(std::max(o.cones.count(), 1));
    if (o.quadrics) bytes += 48 * texels;
    return bytes;
}

/// Sub-voxels per axis of a scene's "mesh" (mesoSolidFromMesh).
inline constexpr int kMesoSceneSolidSub = 2;

/// The peak memory of voxelising a mesh (mesoSolidFromMesh with `sub` sub-voxels per axis) and
/// building its distance map and the DDM of `cones` (`dispmap meso --mesh`): the sub-voxels,
/// the per-voxel triangle lists, the distance transforms in double on the sub-voxel grid, the
/// dense and compressed DDM.
inline std::uint64_t mesoSolidBuildBytes(int width, int height, int layers, int sub, const ConeSet& cones) {
    const std::uint64_t voxels = static_cast<std::uint64_t>(std::max(width, 0)) * static_cast<std::uint64_t>(std::max(height, 0)) *
                                 static_cast<std::uint64_t>(std::max(layers, 0));
    const std::uint64_t s3 = static_cast<std::uint64_t>(sub) * static_cast<std::uint64_t>(sub) * static_cast<std::uint64_t>(sub);
    return voxels * (s3 * (1 + 2 * 8) + 24 + 1 + 4 + 2 * 4 * static_cast<std::uint64_t>(std::max(cones.count(), 1)));
}

/// Why maps of a width x height x layers field cannot be built with these options, or "":
/// sizes and layers out of range, unsupported cones, a compression block outside 1..32 or not
/// dividing width, height and layers (with a DDM), a compression spread < 0 or NaN (with a
/// DDM), distance-map subsamples outside 1..16, or
/// more than kMaxMesoBuildBytes of memory. Everything buildMesoMaps would throw on, found
/// before it starts (the maps take seconds to minutes).
inline std::string mesoBuildProblem(int width, int height, int layers, const MesoMapOptions& o) {
    try {
        detail::checkMesoSize("mesostructure", width, height, layers);
        o.cones.validate();
    } catch (const ArgumentError& e) {
        return e.what();
    }
    if (o.ddm && (o.block < 1 || o.block > 32 || width % o.block || height % o.block || layers % o.block))
        return "compression block " + std::to_string(o.block) + " must be in 1..32 and divide the width, height and layers (" +
               std::to_string(width) + " x " + std::to_string(height) + " x " + std::to_string(layers) + ")";
    if (o.ddm && !(o.compressionSpread >= 0.0f))
        return "compression spread " + std::to_string(o.compressionSpread) + " must be >= 0 voxels (+Inf: the paper's rule)";
    if (o.distance && (o.distanceSubsamples < 1 || o.distanceSubsamples > 16))
        return "distance map subsamples " + std::to_string(o.distanceSubsamples) + " not in 1..16";
    if (const std::uint64_t bytes = mesoBuildBytes(width, height, layers, o); bytes > kMaxMesoBuildBytes)
        return "the maps of " + std::to_string(width) + " x " + std::to_string(height) + " x " + std::to_string(layers) + " voxels (cones " +
               o.cones.name() + ") would take about " + std::to_string(bytes >> 20) + " MiB while they are built, more than " +
               std::to_string(kMaxMesoBuildBytes >> 20) + " MiB: fewer texels (size), layers or cones";
    return {};
}

/// The procedural height fields of the scenes (voxels): "grating" (walls one texel wide and
/// one-texel beads) and "waves".
inline MesoHeightField mesoFunctionField(const std::string& function, int size, int layers) {
    detail::checkMesoSize("mesostructure function", size, size, layers);
    std::vector<float> h(static_cast<std::size_t>(size) * static_cast<std::size_t>(size));
    const double L = layers;
    for (int j = 0; j < size; ++j)
        for (int i = 0; i < size; ++i) {
            double v;
            if (function == "grating") {
                v = L * (0.125 + 0.09 * std::sin(0.2 * i) * std::sin(0.15 * j));
                if (i % 8 == 3) v = 0.875 * L;
                if (i % 8 == 7 && j % 6 == 2) v = 0.7 * L;
            } else if (function == "waves") {
                v = L * (0.45 + 0.35 * std::sin(6.283185307179586 * 2 * i / size) * std::cos(6.283185307179586 * 3 * j / size));
            } else {
                throw ArgumentError("mesostructure: unknown function '" + function + "' (grating, waves)");
            }
            h[static_cast<std::size_t>(j * size + i)] = static_cast<float>(std::clamp(v, 0.0, L));
        }
    return mesoHeightField(size, size, layers, std::move(h));
}

namespace detail {
/// The texels along one side of an image (n of them) that sample i of `size` covers when the
/// side is cut into `size` equal parts: [first, first + weight.size()), each weighted by the
/// part of it inside [i n / size, (i + 1) n / size) (1 for a whole texel).
struct BoxFootprint {
    int first = 0;
    std::vector<double> weight;
};
inline std::vector<BoxFootprint> boxFootprints(int n, int size) {
    std::vector<BoxFootprint> out(static_cast<std::size_t>(size));
    const double scale = static_cast<double>(n) / size;
    for (int i = 0; i < size; ++i) {
        const double lo = i * scale, hi = i + 1 == size ? static_cast<double>(n) : (i + 1) * scale;
        BoxFootprint& f = out[static_cast<std::size_t>(i)];
        f.first = static_cast<int>(std::floor(lo));
        for (int t = f.first; t < n && t < hi; ++t) f.weight.push_back(std::min(t + 1.0, hi) - std::max(static_cast<double>(t), lo));
    }
    return out;
}
} // namespace detail

/// The image box-filtered to size x size: each field sample is the mean of the part of the
/// image its square of the tile covers, width / size x height / size texels, the texels cut by
/// the square's border weighted by the part of them inside (all of the image is used; where
/// size divides both sides these are plain block means). Throws ArgumentError for a size below
/// 2 or larger than a side.
inline HeightImage downsampleHeightImage(const HeightImage& img, int size) {
    if (size < 2) throw ArgumentError("downsampleHeightImage: size " + std::to_string(size) + " is below 2");
    if (img.width < size || img.height < size)
        throw ArgumentError("downsampleHeightImage: size " + std::to_string(size) + ": the image (" + std::to_string(img.width) + " x " +
                            std::to_string(img.height) + ") is smaller");
    const std::vector<detail::BoxFootprint> xs = detail::boxFootprints(img.width, size), ys = detail::boxFootprints(img.height, size);
    const double area = (static_cast<double>(img.width) / size) * (static_cast<double>(img.height) / size);
    HeightImage small;
    small.width = small.height = size;
    small.values.assign(static_cast<std::size_t>(size) * static_cast<std::size_t>(size), 0.0f);
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            const detail::BoxFootprint &fx = xs[static_cast<std::size_t>(x)], &fy = ys[static_cast<std::size_t>(y)];
            double sum = 0;
            for (std::size_t b = 0; b < fy.weight.size(); ++b)
                for (std::size_t a = 0; a < fx.weight.size(); ++a)
                    sum += fy.weight[b] * fx.weight[a] *
                           static_cast<double>(img.at(fx.first + static_cast<int>(a), fy.first + static_cast<int>(b)));
            small.values[static_cast<std::size_t>(y * size + x)] = static_cast<float>(sum / area);
        }
    return small;
}

namespace detail {
// The bilinear value at (px, py) of a w x h grid that repeats (at(i, j) for i in [0, w), j in
// [0, h)): what an image over one tile shows between its texels.
template <class At> double bilinearWrapped(double px, double py, int w, int h, const At& at) {
    const double x0 = std::floor(px), y0 = std::floor(py), fx = px - x0, fy = py - y0;
    const auto wrap = [](double a, int n) { return static_cast<int>(a - std::floor(a / n) * n) % n; };
    const int i0 = wrap(x0, w), j0 = wrap(y0, h), i1 = i0 + 1 == w ? 0 : i0 + 1, j1 = j0 + 1 == h ? 0 : j0 + 1;
    return (1 - fy) * ((1 - fx) * at(i0, j0) + fx * at(i1, j0)) + fy * ((1 - fx) * at(i0, j1) + fx * at(i1, j1));
}
} // namespace detail

/// The height image lined up with the field made from it at `size`: all of it, resampled
/// bilinearly (wrapping) (fx - 1) / 2 and (fy - 1) / 2 texels on (fx = width / size, fy =
/// height / size, not necessarily whole), so that the point fx i, fy j, which sits on the
/// field's sample (i, j), holds the centre of the square the sample averages
/// (downsampleHeightImage). The image itself when size is 0 or its width. For a tool that
/// wants the aligned heights themselves; a scene's images are not resampled but read with
/// that shift (MesoAlbedo::shift), which keeps their sharpness.
inline HeightImage fieldAlignedHeightImage(const HeightImage& img, int size) {
    if (size == 0 || size == img.width) return img;
    const int w = img.width, h = img.height;
    if (size < 0 || w < size || h < size)
        throw ArgumentError("fieldAlignedHeightImage: size " + std::to_string(size) + ": the image (" + std::to_string(img.width) + " x " +
                            std::to_string(img.height) + ") is smaller");
    const double fx = static_cast<double>(w) / size, fy = static_cast<double>(h) / size;
    const double ox = 0.5 * (fx - 1), oy = 0.5 * (fy - 1);
    HeightImage out;
    out.width = w;
    out.height = h;
    out.values.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            out.values[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)] = static_cast<float>(
                detail::bilinearWrapped(x + ox, y + oy, w, h, [&](int a, int b) { return double(img.at(a, b)); }));
    return out;
}

namespace detail {
// A string from the input (a key, a name) for a message, cut to about 80 characters.
inline std::string mesoExcerpt(const std::string& text) { return excerpt(text); }
// Camera coordinates, light components, tile and slab sizes go to the GPU as floats, which
// square them: bounded as a surface draw's values are (kMaxDrawValue, surface/draw.h), and the
// field of view, image size and paths as there and in scene files.

inline void mesoKeys(const nlohmann::json& j, const std::string& scene, const std::string& where, std::initializer_list<const char*> keys) {
    if (!j.is_object()) throw ArgumentError(scene + ": '" + where + "' must be an object");
    for (const auto& [k, v] : j.items()) {
        (void)v;
        bool known = false;
        for (const char* key : keys) known = known || k == key;
        if (!known) throw ArgumentError(scene + ": unknown key '" + (where.empty() ? "" : where + ".") + mesoExcerpt(k) + "'");
    }
}
template <class T> T mesoNumber(const nlohmann::json& j, const char* key, T fallback, const std::string& scene, const std::string& where) {
    if (!j.contains(key)) return fallback;
    const nlohmann::json& v = j[key];
    if (!v.is_number()) throw ArgumentError(scene + ": '" + where + key + "' must be a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) throw ArgumentError(scene + ": '" + where + key + "' is not finite");
    if constexpr (std::is_integral_v<T>) {
        if (d != std::floor(d) || std::abs(d) > 1e9) throw ArgumentError(scene + ": '" + where + key + "' must be an integer");
    } else {
        if (std::abs(d) > kMaxDrawValue)
            throw ArgumentError(scene + ": '" + where + key + "' is beyond +-" + drawNumber(kMaxDrawValue) + " (the GPU holds it as a float)");
    }
    return static_cast<T>(d);
}
inline glm::dvec3 mesoVec3(const nlohmann::json& j, const char* key, glm::dvec3 fallback, const std::string& scene, const std::string& where) {
    if (!j.contains(key)) return fallback;
    const nlohmann::json& v = j[key];
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
        throw ArgumentError(scene + ": '" + where + key + "' must be [x, y, z]");
    const glm::dvec3 r(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
    for (int i = 0; i < 3; ++i)
        if (!(std::abs(r[i]) <= kMaxDrawValue))
            throw ArgumentError(scene + ": '" + where + key + "' is not finite or beyond +-" + drawNumber(kMaxDrawValue) +
                                " (the GPU holds it as a float)");
    return r;
}
inline MesoMapOptions mesoSceneMapOptions(const MesoSceneDesc& s) {
    // The DDM's bent rays rise again (upward cones); relief mapping and POM read only heights.
    MesoMapOptions o = mesoMapOptionsFor(s.technique, s.shadows || (s.bentRays && s.technique.method == MesoMethod::Ddm), s.cones);
    o.block = s.block;
    return o;
}
} // namespace detail

namespace detail {
// A "repeat": tiles per UV unit or per face, a number or [s, t], each in (0, 1e4].
inline glm::dvec2 mesoRepeat(const nlohmann::json& r, const std::string& scene, const std::string& key) {
    glm::dvec2 out;
    if (r.is_number()) out = glm::dvec2(r.get<double>());
    else if (r.is_array() && r.size() == 2 && r[0].is_number() && r[1].is_number()) out = {r[0].get<double>(), r[1].get<double>()};
    else throw ArgumentError(scene + ": '" + key + "' must be a number or [s, t]");
    for (int i = 0; i < 2; ++i)
        if (!(out[i] > 0 && out[i] <= 1e4)) throw ArgumentError(scene + ": '" + key + "' must be in (0, 1e4] tiles");
    return out;
}

// The "base" object of a mesostructure scene (see the header): its surface keys go to the
// surface scene parser (no displacement given: "zero"), the rest are the frame mesh's.
inline void parseMesoBase(const nlohmann::json& b, const std::string& name, const std::string& baseDir, MesoSceneDesc& s) {
    const auto fail = [&](const std::string& why) { return ArgumentError(name + ": " + why); };
    mesoKeys(b, name, "base", {"mesh", "isolation", "endCaps", "displacement", "placement", "repeat", "uv", "tessellation"});
    if (!b.contains("mesh")) throw fail("'base.mesh' is missing (an OBJ path, \"builtin:box\" or \"builtin:torus\")");
    nlohmann::json doc = nlohmann::json::object();
    for (const char* key : {"mesh", "isolation", "endCaps", "displacement"})
        if (b.contains(key)) doc[key] = b[key];
    if (!doc.contains("displacement")) doc["displacement"] = {{"function", "zero"}};
    s.base = parseSceneDocument(doc, name + " (base)", baseDir);
    if (b.contains("placement")) {
        const std::string p = b["placement"].is_string() ? b["placement"].get<std::string>() : "";
        if (p == "uv") s.placement.placement = FramePlacement::Uv;
        else if (p == "face") s.placement.placement = FramePlacement::Face;
        else throw fail("unknown 'base.placement' '" + mesoExcerpt(p) + "' (uv, face)");
    }
    if (b.contains("repeat")) s.placement.repeat = mesoRepeat(b["repeat"], name, "base.repeat");
    if (b.contains("uv")) {
        const std::string u = b["uv"].is_string() ? b["uv"].get<std::string>() : "";
        const std::optional<UvInterpolation> rule = parseUvInterpolation(u);
        if (!rule) throw fail("unknown 'base.uv' '" + mesoExcerpt(u) + "' (mesh, linear, smooth, corners, corners+1, corners+2, boundaries)");
        s.uvRule = *rule;
    }
    s.tessellation = mesoNumber(b, "tessellation", s.tessellation, name, "base.");
    if (!(s.tessellation >= 1 && s.tessellation <= 64)) throw fail("'base.tessellation' must be in 1..64 segments a face edge");
}
} // namespace detail

namespace detail {
// The keys of one mesostructure (an object of "mesostructure", or of its array) into `s`, a
// copy of the scene's description, and the checks that need them and the scene's effects.
inline void parseMesoPart(const nlohmann::json& m, const std::string& baseDir, MesoSceneDesc& s) {
    const std::string& name = s.name;
    const std::string& where = s.key;
    const auto fail = [&](const std::string& why) { return ArgumentError(name + ": " + why); };
    mesoKeys(m, name, where,
             {"material", "height", "function", "mesh", "meshTile", "size", "layers", "depth", "cones", "block", "albedo", "normals", "normalScale",
              "normalGreen", "repeat", "slab"});
    // Its own tile size on the base and slab depth, in place of the scene's.
    if (m.contains("repeat")) {
        if (!s.base) throw fail("'" + where + ".repeat' needs a 'base' (on the plane 'tile' sizes the tiles)");
        s.placement.repeat = mesoRepeat(m["repeat"], name, where + ".repeat");
    }
    s.slab = mesoNumber(m, "slab", s.slab, name, where + ".");
    if (!(s.slab > 0)) throw fail("'" + where + ".slab' must be > 0");
    if (m.contains("material")) {
        if (!m["material"].is_string() || m["material"].get_ref<const std::string&>().empty())
            throw fail("'" + where + ".material' must be a material's name (OBJ usemtl)");
        s.material = m["material"].get<std::string>();
    }
    const auto path = [&](const char* key) {
        if (!m[key].is_string()) throw fail("'" + where + "." + key + "' must be a file name");
        const std::string& h = m[key].get_ref<const std::string&>();
        if (h.empty()) throw fail("'" + where + "." + key + "' is empty");
        if (h.size() > kMaxScenePathLength)
            throw fail("'" + where + "." + key + "' is a path of " + std::to_string(h.size()) + " characters, longer than " +
                       std::to_string(kMaxScenePathLength));
        const std::filesystem::path p(h);
        return p.is_absolute() || baseDir.empty() ? p.string() : (std::filesystem::path(baseDir) / p).string();
    };
    if (m.contains("height")) s.heightImage = path("height");
    if (m.contains("mesh")) {
        if (m.contains("height") || m.contains("function"))
            throw fail("'" + where + ".mesh' is the detail itself: no 'height' or 'function' beside it");
        // What a solid's march does not have: a depth of white, normals from or over heights,
        // and every technique but the DDM's (the others read heights; meso.frag).
        for (const char* key : {"depth", "normals"})
            if (m.contains(key)) throw fail("'" + where + "." + key + "' applies to a height field, not to a 'mesh'");
        if (s.technique.method != MesoMethod::Ddm)
            throw fail("'" + where + ".mesh' (non-height-field detail) is marched by the DDM: 'effects.technique' must be \"ddm\"");
        s.mesh = path("mesh");
    }
    if (m.contains("meshTile")) {
        if (s.mesh.empty()) throw fail("'" + where + ".meshTile' without '" + where + ".mesh'");
        const nlohmann::json& mt = m["meshTile"];
        mesoKeys(mt, name, where + ".meshTile", {"corner", "size"});
        if (!mt.contains("corner") || !mt.contains("size")) throw fail("'" + where + ".meshTile' needs 'corner' [x, y, z] and 'size'");
        MesoSolidTile tile;
        tile.corner = mesoVec3(mt, "corner", tile.corner, name, where + ".meshTile.");
        tile.size = mesoNumber(mt, "size", tile.size, name, where + ".meshTile.");
        if (!(tile.size > 0) || !std::isfinite(tile.size)) throw fail("'" + where + ".meshTile.size' must be > 0 (mesh units a tile)");
        s.meshTile = tile;
    }
    if (m.contains("albedo")) s.albedoImage = path("albedo");
    if (m.contains("normals")) {
        if (m["normals"].is_string() && m["normals"].get_ref<const std::string&>() == "height") s.normalsFromHeight = true;
        else s.normalsImage = path("normals");
    }
    for (const char* key : {"normalScale", "normalGreen"})
        if (m.contains(key) && !m.contains("normals")) throw fail("'" + where + "." + key + "' without '" + where + ".normals'");
    s.normalScale = mesoNumber(m, "normalScale", s.normalScale, name, where + ".");
    if (!(std::abs(s.normalScale) <= kMaxNormalScale))
        throw fail("'" + where + ".normalScale' " + detail::drawNumber(s.normalScale) + " is not within +-" + detail::drawNumber(kMaxNormalScale));
    if (m.contains("normalGreen")) {
        const std::string g = m["normalGreen"].is_string() ? m["normalGreen"].get<std::string>() : "";
        if (g != "up" && g != "down") throw fail("'" + where + ".normalGreen' must be \"up\" (OpenGL, glTF) or \"down\" (DirectX)");
        s.normalGreenUp = g == "up";
    }
    if (m.contains("function")) {
        if (!m["function"].is_string()) throw fail("'" + where + ".function' must be a name");
        s.function = m["function"].get<std::string>();
    }
    if (s.heightImage.empty() && s.function != "grating" && s.function != "waves")
        throw fail("'" + where + ".function': unknown function '" + mesoExcerpt(s.function) + "' (grating, waves)");
    s.size = mesoNumber(m, "size", s.heightImage.empty() ? 64 : 0, name, where + ".");
    if (!s.mesh.empty() && s.size == 0) throw fail("'" + where + ".size' 0: a 'mesh' needs the voxels per side of its tile");
    s.layers = mesoNumber(m, "layers", s.layers, name, where + ".");
    s.depth = mesoNumber(m, "depth", s.depth, name, where + ".");
    s.block = mesoNumber(m, "block", s.block, name, where + ".");
    if (m.contains("cones")) {
        if (!m["cones"].is_string()) throw fail("'" + where + ".cones' must be \"MxN\" or \"isotropic\"");
        try {
            s.cones = parseConeSet(mesoExcerpt(m["cones"].get<std::string>()));
        } catch (const ArgumentError& e) {
            throw fail(std::string("'" + where + ".cones': ") + e.what());
        }
    }
    if (s.layers < 2 || s.layers > kMaxMesoLayers) throw fail("'" + where + ".layers' out of range (2 .. 256)");
    if (s.heightImage.empty() ? (s.size < 2 || s.size > kMaxMesoSize) : (s.size != 0 && (s.size < 2 || s.size > kMaxMesoSize)))
        throw fail("'" + where + ".size' " + std::to_string(s.size) + " out of range (2 .. " + std::to_string(kMaxMesoSize) + ")" +
                   (s.heightImage.empty() ? "" : " (or 0: the image's size)"));
    if (s.depth != -1 && !(s.depth > 0 && s.depth <= s.layers))
        throw fail("'" + where + ".depth' " + std::to_string(s.depth) + " is not in (0, layers = " + std::to_string(s.layers) + "]");
    if (s.block < 1 || s.block > 32) throw fail("'" + where + ".block' " + std::to_string(s.block) + " is not in 1..32");
    if (s.size > 0)
        if (const std::string why = mesoBuildProblem(s.size, s.size, s.layers, mesoSceneMapOptions(s)); !why.empty())
            throw fail("'" + where + "': " + why);
    if (!s.mesh.empty())
        if (const std::uint64_t bytes = mesoSolidBuildBytes(s.size, s.size, s.layers, kMesoSceneSolidSub, s.cones); bytes > kMaxMesoBuildBytes)
            throw fail("'" + where + ".mesh' voxelised into " + std::to_string(s.size) + " x " + std::to_string(s.size) + " x " +
                       std::to_string(s.layers) + " voxels would take about " + std::to_string(bytes >> 20) + " MiB while its maps are built, more than " +
                       std::to_string(kMaxMesoBuildBytes >> 20) + " MiB: a smaller 'size' or fewer 'layers'");
}
} // namespace detail

/// Whether a scene file's JSON is a mesostructure scene (it has the "mesostructure" key).
inline bool isMesoScene(const nlohmann::json& j) { return j.is_object() && j.contains("mesostructure"); }

/// Reads a mesostructure scene (the JSON of parseSceneJson, scene/scene.h). Every value is
/// checked here, before any map is built: unknown keys, types, ranges (the renderer's and
/// the map builders': layers, size, block dividing size and layers, cones, depth, the marchers'
/// step counts up to kMaxMesoIterations / kMaxMesoLinearSteps / kMaxMesoBinarySteps, a camera
/// above the plane that does not look from its target, a light that is not zero and, with
/// shadows, above the horizon, the memory of the maps when the size is known). ArgumentError
/// naming the scene and the key.
inline MesoSceneDesc parseMesoScene(const nlohmann::json& j, const std::string& name, const std::string& baseDir) {
    using namespace detail;
    MesoSceneDesc s;
    s.name = name;
    const auto fail = [&](const std::string& why) { return ArgumentError(name + ": " + why); };
    mesoKeys(j, name, "", {"mesostructure", "camera", "light", "resolution", "tile", "slab", "checker", "effects", "base"});
    if (j.contains("camera")) {
        const nlohmann::json& c = j["camera"];
        mesoKeys(c, name, "camera", {"eye", "target", "up", "fov"});
        s.eye = mesoVec3(c, "eye", s.eye, name, "camera.");
        s.target = mesoVec3(c, "target", s.target, name, "camera.");
        s.up = mesoVec3(c, "up", s.up, name, "camera.");
        s.fov = mesoNumber(c, "fov", s.fov, name, "camera.");
    }
    s.light = mesoVec3(j, "light", s.light, name, "");
    if (j.contains("resolution")) {
        const nlohmann::json& r = j["resolution"];
        if (!r.is_array() || r.size() != 2 || !r[0].is_number_integer() || !r[1].is_number_integer())
            throw fail("'resolution' must be [width, height]");
        // As 64-bit integers (huge unsigned ones clamped): 4294967297 must not wrap to 1.
        const auto side = [](const nlohmann::json& v) -> std::int64_t {
            if (v.is_number_unsigned()) return static_cast<std::int64_t>(std::min<std::uint64_t>(v.get<std::uint64_t>(), std::uint64_t{1} << 40));
            return v.get<std::int64_t>();
        };
        const std::int64_t w = side(r[0]), h = side(r[1]);
        if (w < 1 || h < 1 || w > kMaxImageSize || h > kMaxImageSize)
            throw fail("'resolution' " + std::to_string(w) + " x " + std::to_string(h) + " is out of range (1 .. " +
                       std::to_string(kMaxImageSize) + ")");
        s.width = static_cast<int>(w);
        s.height = static_cast<int>(h);
    }
    s.tile = mesoNumber(j, "tile", s.tile, name, "");
    s.slab = mesoNumber(j, "slab", s.slab, name, "");
    if (!(s.tile > 0) || !(s.slab > 0)) throw fail("'tile' and 'slab' must be > 0");
    s.checker = mesoNumber(j, "checker", s.checker, name, "");
    if (!(s.checker >= 0 && s.checker <= 1e6)) throw fail("'checker' must be in [0, 1e6] voxels (0: no checker)");
    if (j.contains("effects")) {
        const nlohmann::json& e = j["effects"];
        mesoKeys(e, name, "effects", {"technique", "quadrics", "iterations", "exitRule", "eps", "linear", "binary", "shadows", "mips",
                                            "silhouettes", "bentRays"});
        MesoTechnique& t = s.technique;
        if (e.contains("technique")) {
            const std::string k = e["technique"].is_string() ? e["technique"].get<std::string>() : "";
            if (k == "ddm") t.method = MesoMethod::Ddm;
            else if (k == "distance_map") t.method = MesoMethod::DistanceMap;
            else if (k == "relief") t.method = MesoMethod::Relief;
            else if (k == "pom") t.method = MesoMethod::Pom;
            else throw fail("unknown 'effects.technique' '" + mesoExcerpt(k) + "' (ddm, distance_map, relief, pom)");
        }
        const auto flag = [&](const char* key, bool fallback) {
            if (!e.contains(key)) return fallback;
            if (!e[key].is_boolean()) throw fail(std::string("'effects.") + key + "' must be true or false");
            return e[key].get<bool>();
        };
        t.quadrics = flag("quadrics", t.quadrics);
        s.shadows = flag("shadows", s.shadows);
        s.silhouettes = flag("silhouettes", s.silhouettes);
        s.bentRays = flag("bentRays", s.bentRays);
        s.albedoMips = flag("mips", s.albedoMips);
        t.iterations = mesoNumber(e, "iterations", t.iterations, name, "effects.");
        t.exitRule = mesoNumber(e, "exitRule", t.exitRule, name, "effects.");
        t.eps = mesoNumber(e, "eps", t.eps, name, "effects.");
        t.linear = mesoNumber(e, "linear", t.linear, name, "effects.");
        t.binary = mesoNumber(e, "binary", t.binary, name, "effects.");
        if (t.iterations < 1 || t.linear < 1 || t.binary < 0 || (t.exitRule != 0 && t.exitRule != 1))
            throw fail("'effects' iterations and linear must be >= 1, binary >= 0, exitRule 0 or 1");
        if (t.iterations > kMaxMesoIterations || t.linear > kMaxMesoLinearSteps || t.binary > kMaxMesoBinarySteps)
            throw fail("'effects' iterations " + std::to_string(t.iterations) + ", linear " + std::to_string(t.linear) + ", binary " +
                       std::to_string(t.binary) + ": at most " + std::to_string(kMaxMesoIterations) + ", " +
                       std::to_string(kMaxMesoLinearSteps) + " and " + std::to_string(kMaxMesoBinarySteps) +
                       " (more steps change no pixel)");
    }
    // The renderer's rules, here so that no map is built for a scene it would refuse.
    if (!(s.fov >= kMinFovDeg && s.fov < 180))
        throw fail("'camera.fov' " + std::to_string(s.fov) + " is not in [" + detail::drawNumber(kMinFovDeg) + ", 180) degrees");
    if (j.contains("base")) parseMesoBase(j["base"], name, baseDir, s);
    if (s.silhouettes && !s.base) throw fail("'effects.silhouettes' needs a 'base' (the plane z = 0 has no silhouettes of its own)");
    if (s.bentRays && !s.base) throw fail("'effects.bentRays' needs a 'base' (the plane z = 0 is not curved)");
    s.placement.shape = s.silhouettes || s.bentRays;
    if (!s.base && !(s.eye.z > 0)) throw fail("'camera.eye' must be above the plane z = 0 (eye.z > 0)");
    if (!(glm::length(s.target - s.eye) > 0)) throw fail("'camera.eye' and 'camera.target' are the same point");
    if (!(glm::length(glm::cross(s.target - s.eye, s.up)) > 1e-9 * glm::length(s.target - s.eye) * glm::length(s.up)))
        throw fail("'camera.up' is zero or parallel to the view direction");
    if (!s.base && !(s.up.x == 0 && s.up.y == 0 && s.up.z > 0)) throw fail("'camera.up' must be +z over the plane (another with a 'base')");
    if (!(glm::length(s.light) > 0)) throw fail("'light' is the zero vector");
    if (!s.base && s.shadows && !(s.light.z > 0)) throw fail("'light' must be above the horizon (z > 0) with 'effects.shadows'");
    // The mesostructures: one object, or an array of them placed by material.
    const nlohmann::json& ms = j["mesostructure"];
    if (ms.is_array()) {
        if (ms.empty() || ms.size() > kMaxMesoParts)
            throw fail("'mesostructure' is an array of " + std::to_string(ms.size()) + " mesostructures (1 .. " + std::to_string(kMaxMesoParts) + ")");
        if (!s.base) throw fail("'mesostructure' as an array needs a 'base' (its mesostructures lie on the base's materials)");
    }
    const std::size_t count = ms.is_array() ? ms.size() : 1;
    const MesoSceneDesc scene = s;
    for (std::size_t i = 0; i < count; ++i) {
        MesoSceneDesc& part = i == 0 ? s : s.others.emplace_back(scene);
        part.part = static_cast<int>(i);
        part.key = ms.is_array() ? "mesostructure[" + std::to_string(i) + "]" : "mesostructure";
        parseMesoPart(ms.is_array() ? ms[i] : ms, baseDir, part);
        if (!part.material.empty() && !s.base) throw fail("'" + part.key + ".material' needs a 'base' (the plane has no materials)");
        for (std::size_t k = 0; k < i; ++k) {
            const MesoSceneDesc& other = k == 0 ? s : s.others[k - 1];
            if (other.material == part.material)
                throw fail(part.material.empty() ? "'" + other.key + "' and '" + part.key + "' both lack a 'material' (one mesostructure covers the faces no other claims)"
                                                 : "'" + other.key + "' and '" + part.key + "' are both on material '" + mesoExcerpt(part.material) + "'");
        }
    }
    return s;
}

/// The scene's height field (the image box-filtered to `size`, or the function), and the maps
/// its effects need (mesoMapOptionsFor): nothing else is built. A "mesh" is voxelised into
/// size x size x layers voxels (mesoSolidFromMesh: its bounding box's x and y scaled onto the
/// tile, z alike from the floor up) and gets a solid's maps (buildMesoSolidMaps). Everything the builders would
/// throw on is checked first (mesoBuildProblem), and an image above kMaxMesoSize without a
/// `size` to filter it to is refused from its header, before it is decoded.
inline MesoMaps buildMesoSceneMaps(const MesoSceneDesc& s) {
    MesoHeightField field;
    const double depth = s.depth > 0 ? s.depth : 0.875 * s.layers;
    const MesoMapOptions o = detail::mesoSceneMapOptions(s);
    const auto check = [&](int width, int height) {
        if (const std::string why = mesoBuildProblem(width, height, s.layers, o); !why.empty())
            throw ArgumentError(s.name + ": '" + s.key + "': " + why);
    };
    if (!s.mesh.empty()) {
        check(s.size, s.size);
        const TriangleSoup soup = readObjTriangles(s.mesh);
        try {
            return buildMesoSolidMaps(s.meshTile ? mesoSolidFromMesh(soup.positions, soup.triangles, s.size, s.size, s.layers, *s.meshTile, kMesoSceneSolidSub)
                                                 : mesoSolidFromMesh(soup.positions, soup.triangles, s.size, s.size, s.layers, kMesoSceneSolidSub),
                                      o);
        } catch (const ArgumentError& e) {
            throw ArgumentError(s.name + ": '" + s.key + ".mesh': " + e.what());
        }
    }
    if (!s.heightImage.empty()) {
        HeightImage img = readHeightPng(s.heightImage, s.size > 0 ? kMaxHeightImageSize : kMaxMesoSize,
                                        " (give '" + s.key + ".size' to box-filter it smaller)");
        if (s.size > 0 && s.size != img.width) img = downsampleHeightImage(img, s.size);
        check(img.width, img.height);
        field = mesoHeightFieldFromImage(img, s.layers, depth);
    } else {
        check(s.size, s.size);
        field = mesoFunctionField(s.function, s.size, s.layers);
    }
    return buildMesoMaps(field, o);
}

namespace detail {
// Where an image over one tile must be read from so that it lines up with the height field of
// `s`, in texels of that width x height image. Every image here is a grid of area samples of
// the tile (a texel the mean of its square, as the field's samples are the means of the height
// image's blocks), and the renderer puts texel x of a w-wide image at x / w of the tile
// (kern::dmMesoImageBilinear; field sample i at voxel i), half a texel before the centre of
// its square: half a field sample for the geometry, half a texel for the image. Read
// (w / W - 1) / 2 texels on (W the field's width), an image shows at each sample the colour of
// the square that sample averages: (fx - 1) / 2 for an image of the height image's size filtered
// fx to 1, 0 at the field's own size. 0 for a function's field (point samples, no image).
inline glm::dvec2 mesoImageShift(const MesoSceneDesc& s, int width, int height) {
    if (s.heightImage.empty()) return glm::dvec2(0.0);
    const PngSize h = readPngSize(s.heightImage, "height image");
    // The field's samples: the image box-filtered to size x size, or the image itself
    // (buildMesoSceneMaps filters when the size is given and is not the image's width).
    const bool filtered = s.size > 0 && s.size != h.width;
    const double W = filtered ? s.size : h.width, H = filtered ? s.size : h.height;
    return {0.5 * (width / W - 1.0), 0.5 * (height / H - 1.0)};
}

} // namespace detail

/// The scene's albedo ("mesostructure.albedo", with its mips unless "effects.mips" is false),
/// or none. Over a field made from a height image it is read so that each sample has the
/// colour of the square it averages (detail::mesoImageShift: (fx - 1) / 2 texels on for an
/// image of the height image's size filtered fx to 1, as a normal map is), by the albedo's own
/// shift where it is sampled (MesoAlbedo::shift: the image itself is not resampled).
/// FileError for an image that cannot be read, ArgumentError (naming the scene) for one larger
/// than kMaxMesoAlbedoSize.
inline std::shared_ptr<const MesoAlbedo> buildMesoSceneAlbedo(const MesoSceneDesc& s) {
    if (s.albedoImage.empty()) return nullptr;
    const RgbaImage img = readRgbaPng(s.albedoImage, kMaxMesoAlbedoSize);
    try {
        return std::make_shared<const MesoAlbedo>(
            mesoAlbedo(img.width, img.height, img.rgba, s.albedoMips, glm::vec2(detail::mesoImageShift(s, img.width, img.height))));
    } catch (const ArgumentError& e) {
        throw ArgumentError(s.name + ": '" + s.key + ".albedo': " + e.what());
    }
}

/// The scene's normal map ("mesostructure.normals", with its mips unless "effects.mips" is
/// false), or none: the PNG, or with "height" normalMapFromHeights of the height image at its
/// full resolution (the function's field at `size` without an image), either read with the
/// albedo's shift (buildMesoSceneAlbedo), the slope from white's
/// depth (slab depth / layers) over a tile's width: `tile` on the plane, the base's
/// meanTileWidth() when `base` (the scene's, buildMesoSceneBase) is given. FileError for an
/// image that cannot be read, ArgumentError (naming the scene) for one larger than
/// kMaxMesoAlbedoSize or a base without corners.
inline std::shared_ptr<const MesoAlbedo> buildMesoSceneNormals(const MesoSceneDesc& s, const FrameMesh* base = nullptr) {
    try {
        if (!s.normalsImage.empty()) {
            const RgbaImage img = readRgbaPng(s.normalsImage, kMaxMesoAlbedoSize);
            return std::make_shared<const MesoAlbedo>(
                mesoAlbedo(img.width, img.height, img.rgba, s.albedoMips, glm::vec2(detail::mesoImageShift(s, img.width, img.height)))); // as the albedo
        }
        if (!s.normalsFromHeight) return nullptr;
        // Heights in voxels, the slope from voxels of height to tile widths.
        HeightImage heights;
        const double depth = s.depth > 0 ? s.depth : 0.875 * s.layers;
        glm::vec2 shift(0.0f); // a height image's normal map is read as its albedo would be
        if (!s.heightImage.empty()) {
            heights = readHeightPng(s.heightImage, kMaxMesoAlbedoSize, " (the largest normal map made from heights)");
            shift = glm::vec2(detail::mesoImageShift(s, heights.width, heights.height));
            for (float& v : heights.values) v = static_cast<float>(std::clamp(double(v), 0.0, 1.0) * depth);
        } else {
            const MesoHeightField f = mesoFunctionField(s.function, s.size, s.layers);
            heights.width = f.width;
            heights.height = f.height;
            heights.values = f.h;
        }
        // The tile's width on the base: over this mesostructure's own triangles on a grouped base.
        double tile = s.tile;
        if (base && !base->groups.empty() && static_cast<std::size_t>(s.part) < base->groups.size()) {
            std::size_t first = 0;
            for (int g = 0; g < s.part; ++g) first += static_cast<std::size_t>(base->groups[static_cast<std::size_t>(g)]);
            tile = base->meanTileWidth(first, static_cast<std::size_t>(base->groups[static_cast<std::size_t>(s.part)]));
        } else if (base) {
            tile = base->meanTileWidth();
        }
        if (!(tile > 0)) throw ArgumentError("the base has no tile width to take slopes over");
        const std::vector<std::uint8_t> rgba = normalMapFromHeights(heights, s.slab / (s.layers * tile));
        return std::make_shared<const MesoAlbedo>(mesoAlbedo(heights.width, heights.height, rgba, s.albedoMips, shift));
    } catch (const ArgumentError& e) {
        throw ArgumentError(s.name + ": '" + s.key + ".normals': " + e.what());
    }
}

namespace detail {
// Each ptex face's mesostructure (its index in mesoSceneParts) from its control face's
// material (see buildMesoSceneBase).
inline std::vector<int> mesoPartOfFace(const MesoSceneDesc& s, const ControlMesh& mesh) {
    const std::vector<MesoSceneDesc> parts = mesoSceneParts(s);
    const MeshDescription& d = mesh.description();
    const auto list = [&] {
        std::string names;
        for (const std::string& m : d.materials) names += (names.empty() ? "" : ", ") + mesoExcerpt(m);
        return names.empty() ? std::string("it names no material: OBJ usemtl") : "its materials: " + names;
    };
    // Each material's part, and the part of faces without one of their own.
    int rest = -1;
    std::vector<int> ofMaterial(d.materials.size(), -1);
    for (const MesoSceneDesc& p : parts) {
        if (p.material.empty()) {
            rest = p.part;
            continue;
        }
        const auto at = std::find(d.materials.begin(), d.materials.end(), p.material);
        if (at == d.materials.end())
            throw ArgumentError("'" + p.key + ".material' '" + mesoExcerpt(p.material) + "' is not a material of the mesh '" + d.name + "' (" +
                                list() + ")");
        ofMaterial[static_cast<std::size_t>(at - d.materials.begin())] = p.part;
    }
    std::vector<int> out(static_cast<std::size_t>(mesh.ptexFaceCount()), -1);
    std::vector<char> hole(d.faceSizes.size(), 0);
    for (int h : d.holes) hole[static_cast<std::size_t>(h)] = 1;
    std::vector<std::size_t> faces(parts.size(), 0);
    const int nf = static_cast<int>(d.faceSizes.size());
    for (int f = 0; f < nf; ++f) {
        if (hole[static_cast<std::size_t>(f)]) continue; // no surface, no triangles: under none
        const int m = d.faceMaterials.empty() ? -1 : d.faceMaterials[static_cast<std::size_t>(f)];
        const int part = m >= 0 && ofMaterial[static_cast<std::size_t>(m)] >= 0 ? ofMaterial[static_cast<std::size_t>(m)] : rest;
        if (part < 0)
            throw ArgumentError("face " + std::to_string(f + 1) + " of the mesh '" + d.name + "' (" +
                                (m >= 0 ? "material '" + mesoExcerpt(d.materials[static_cast<std::size_t>(m)]) + "'" : std::string("no material")) +
                                ") lies under no mesostructure: give one that material, or one without a 'material' for the faces no other claims");
        ++faces[static_cast<std::size_t>(part)];
        // Its ptex faces, as OpenSubdiv numbers them (one a quad, one a corner of another face).
        const int first = mesh.ptex().GetFaceId(f), end = f + 1 < nf ? mesh.ptex().GetFaceId(f + 1) : mesh.ptexFaceCount();
        for (int k = first; k < end; ++k) out[static_cast<std::size_t>(k)] = part;
    }
    // Maps built for nothing take seconds and memory: a mesostructure must cover a face.
    for (const MesoSceneDesc& p : parts)
        if (faces[static_cast<std::size_t>(p.part)] == 0)
            throw ArgumentError("'" + p.key + "' covers no face of the mesh '" + d.name + "' (" +
                                (p.material.empty() ? std::string("every face is another's") : "no face of material '" + mesoExcerpt(p.material) + "'") +
                                "): leave it out");
    return out;
}
} // namespace detail

/// The scene's base surface as the renderer draws it (none without "base"): the mesh and its
/// displacement built as a surface scene's (SceneSurface), tessellated uniformly, with the
/// frame of every triangle corner (buildFrameMesh). Throws what those throw: FileError /
/// MeshError for the mesh, ArgumentError naming the scene for UV placement on a mesh without
/// texture coordinates, a singular frame, or more than kMaxFrameCorners / 3 triangles (from
/// the factors, before anything is tessellated). With several mesostructures (or one with a
/// "material") the triangles are grouped by them (groupFrameMesh, in mesoSceneParts' order),
/// each by its control face's OBJ material; ArgumentError for a "material" the mesh does not
/// name, a face (not a hole) under no mesostructure (its material claimed by none, and no
/// mesostructure without a "material"), and a mesostructure that covers no face.
inline std::shared_ptr<const FrameMesh> buildMesoSceneBase(const MesoSceneDesc& s) {
    if (!s.base) return nullptr;
    const SceneSurface surface(*s.base);
    const Tessellator tessellator(surface.surface, uniformTessFactors(surface.base, s.tessellation));
    if (const std::uint64_t triangles = tessellator.estimate().triangles; 3 * triangles > kMaxFrameCorners)
        throw ArgumentError(s.name + ": 'base.tessellation' " + detail::drawNumber(s.tessellation) + " makes " + std::to_string(triangles) +
                            " triangles, more than the " + std::to_string(kMaxFrameCorners / 3) + " a base may have");
    const TriangleMesh tess = tessellator.tessellate();
    try {
        std::optional<UvMap> uv;
        if (s.placement.placement == FramePlacement::Uv) {
            if (!surface.mesh.hasUVs())
                throw ArgumentError("'base.placement' \"uv\" needs texture coordinates and the mesh '" + s.base->mesh +
                                    "' has none (\"placement\": \"face\" tiles every face instead)");
            uv.emplace(surface.mesh, s.uvRule);
        }
        if (s.others.empty() && s.material.empty())
            return std::make_shared<const FrameMesh>(buildFrameMesh(surface.surface, tess, uv ? &*uv : nullptr, s.placement));
        // Several mesostructures: each face's, its repeat where they differ, the triangles grouped.
        const std::vector<int> partOf = detail::mesoPartOfFace(s, surface.mesh);
        const std::vector<MesoSceneDesc> parts = mesoSceneParts(s);
        FrameMeshOptions o = s.placement;
        for (const MesoSceneDesc& p : parts)
            if (p.placement.repeat != s.placement.repeat) {
                o.faceRepeat.assign(partOf.size(), s.placement.repeat);
                for (std::size_t f = 0; f < partOf.size(); ++f)
                    if (partOf[f] >= 0) o.faceRepeat[f] = parts[static_cast<std::size_t>(partOf[f])].placement.repeat;
                break;
            }
        FrameMesh frames = buildFrameMesh(surface.surface, tess, uv ? &*uv : nullptr, o);
        groupFrameMesh(frames, partOf, static_cast<int>(parts.size()));
        return std::make_shared<const FrameMesh>(std::move(frames));
    } catch (const ArgumentError& e) {
        throw ArgumentError(s.name + ": " + e.what());
    }
}

} // namespace dispmap
