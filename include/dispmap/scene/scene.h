#pragma once
// Scene files: what the renderer draws, as JSON (reading and writing them; building the mesh
// and tiles a scene names is scene/build.h). A control mesh (built-in or OBJ), its
// displacement (procedural, a UV-mapped height image, or a saved tile file), a camera, lights,
// the output size and the effects (technique, normals, level of detail, tessellation).
//
//   { "mesh": "builtin:box", "isolation": 6, "endCaps": "gregory",
//     "displacement": {"function": "waves", "height": "", "tiles": "", "scale": 0.07, "offset": 0,
//                      "midLevel": 0, "channel": "", "uv": "mesh", "mapFilter": "point",
//                      "sizes": "uniform", "sizeTolerance": 0.02, "allowOverlap": false,
//                      "wrap": false, "k": 5, "mixedSizes": false, "filter": "haar", "sharpBand": 0.25},
//     "camera": {"eye": [2.6, 2.0, 3.4], "target": [0, 0, 0], "up": [0, 1, 0], "fovY": 40,
//                "near": 0.05, "far": 100},
//     "lights": [{"direction": [0.4, 0.8, 0.5], "color": [1, 1, 1]}],
//     "ambient": 0.15, "albedo": [0.8, 0.78, 0.74], "background": [0, 0, 0],
//     "resolution": [320, 240], "baselineTexels": 0, "baselineLayout": "faces",
//     "effects": {"technique": "displaced", "normals": "approximate", "autoTolerance": 2,
//                 "lod": "tessfactor", "wireframe": false, "texelFormat": "float", "texelPath": "buffer",
//                 "tessellation": {"method": "uniform", "value": 8, "max": 64,
//                                  "spacing": "fractional_even"}} }
//
// Every key is optional (the defaults are the member initialisers below); comments (// and
// /* */) are allowed. Everything else is a SceneError naming the scene and the key path
// (`scene 'x.json': effects.normals: unknown value 'fancy' (approximate, accurate, auto)`):
// invalid JSON (also: nesting deeper than kMaxSceneJsonDepth, a file above kMaxSceneFileBytes),
// a wrong type, an unknown key anywhere, a number out of range or not finite (1e999 is a parse
// error), a displacement above kMaxDisplacement, a path longer than kMaxScenePathLength, and a
// height image together with a tile file. The ranges of the draw (camera, lights, colours,
// image size, effects) are one rule with the renderers': surfaceDrawProblem (surface/draw.h),
// e.g. a camera whose eye equals its target, whose up is parallel to the view direction, or
// whose far / near exceeds kMaxDepthRatio; a zero light direction. Messages quote at most ~80
// characters of the input. Relative paths (mesh, height, tiles) are resolved against the scene
// file's directory.
//
// Tessellation factors (Nießner & Loop 2013, §6.1; kernels/lod.h): "uniform" uses `value` as
// the factor; "distance", "edge" and "area" use it as the constant c of dmTessFactorDistance,
// dmTessFactorEdge and dmTessFactorArea; all are clamped to `max` (1..64, the hardware limit).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "dispmap/surface/uv_map.h"
#include "dispmap/surface/baseline.h"
#include "dispmap/surface/builtin.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/draw.h"
#include "dispmap/core/error.h"
#include "dispmap/core/file_io.h"

namespace dispmap {

/// A scene file that is not valid JSON, or whose content is out of its documented range.
class SceneError : public ArgumentError {
  public:
    using ArgumentError::ArgumentError;
};

/// Largest baseline atlas texels per face edge (baseline.h).
inline constexpr int kMaxBaselineTexels = 1024;

/// Largest scene file: a scene is a few hundred bytes of keys; 1 MiB leaves room for comments
/// while the parsed document (nlohmann's DOM takes tens of bytes per value) stays small.
inline constexpr std::uint64_t kMaxSceneFileBytes = std::uint64_t{1} << 20;
/// Deepest nesting of arrays and objects in a scene file. A scene nests 4 deep; the limit is
/// checked on the text before parsing, since nlohmann's serialiser and comparisons recurse
/// (100,000 nested arrays overflowed the stack).
inline constexpr int kMaxSceneJsonDepth = 64;
/// Longest path a scene may name (mesh, height image, tile file): Linux's PATH_MAX.
inline constexpr std::size_t kMaxScenePathLength = 4096;
/// Largest |offset| + |scale| of a displacement (the bound of |D|, in mesh units). The tiles
/// store D in float and the GPU forms cross products of the displaced derivatives (~2^k D
/// each, k <= 8), whose squared length grows as (2^k D)^4: at 1e6 that is ~1e36, under float's
/// 3.4e38. A displacement a million times a unit mesh is no surface anyway.
inline constexpr double kMaxDisplacement = 1e6;

struct SceneDisplacement {
    /// "waves" (builtin::defaultDisplacement times scale / 0.07, so |D| <= scale) or "zero";
    /// used when height and tiles are both empty.
    std::string function = "waves";
    /// UV-mapped height image (PNG, EXR, TIFF; a UDIM set when the name holds <UDIM>):
    /// D = offset + scale * (h - midLevel) (path as written)
    std::string height;
    std::string tiles;    ///< a saved tile file (.dmt) instead (path as written)
    double scale = 0.07, offset = 0;
    bool wrap = false;    ///< height image: wrap texture coordinates outside [0, 1]
    double midLevel = 0;  ///< height image: the height that means no displacement
    std::string channel;  ///< height image: its channel ("" : the only one, or grey / Y / R)
    std::string uv = "mesh"; ///< height image: UV interpolation (surface/uv_map.h: mesh, linear, smooth, ...)
    std::string mapFilter = "point"; ///< height image: point, box or tent (surface/map_source.h)
    /// "uniform": k everywhere (or mixedSizes); "texels": per face from the image's texel
    /// density, at most k (texelTileSizes); "error": per face the smallest size whose samples
    /// stay within sizeTolerance of 2^k's (errorTileSizes)
    std::string sizes = "uniform";
    /// sizes "error": the error smaller tiles may add, in the map's height units (D / scale), (0, 1]
    double sizeTolerance = 0.02;
    bool allowOverlap = false; ///< height image: accept faces that overlap in UV space
    int k = 5;            ///< log2 tile size of quads (sub-faces of non-quads get k - 1), 1..kMaxTileLog2
    bool mixedSizes = false; ///< quads get k - (ptex face % 3) (>= 1): mixedTileSizes
    std::string filter = "haar"; ///< mip filter: "haar" | "bwavelet"
    /// Band (base-face edges, 0..1/2) over which D fades to 0 at infinitely sharp creases and
    /// corners (DisplacedSurfaceOptions::sharpBand; 0: off, and the creases tear open).
    double sharpBand = 0.25;
};

/// Why the displacement's size is out of range (key "displacement.scale"), or none: scale and
/// offset finite with |offset| + |scale| <= kMaxDisplacement.
inline std::optional<DrawProblem> displacementProblem(const SceneDisplacement& d) {
    const double bound = std::abs(d.offset) + std::abs(d.scale);
    if (!std::isfinite(d.scale)) return DrawProblem{"displacement.scale", "must be finite"};
    if (!std::isfinite(d.offset)) return DrawProblem{"displacement.offset", "must be finite"};
    if (!(bound <= kMaxDisplacement))
        return DrawProblem{"displacement.scale", "|offset| + |scale| = " + detail::drawNumber(bound) + " exceeds " +
                                                     detail::drawNumber(kMaxDisplacement) +
                                                     ", the largest displacement the float evaluation keeps finite"};
    return std::nullopt;
}

/// A scene: a draw (surface/draw.h: camera, lights, image, effects) plus where the surface
/// comes from.
struct Scene : SurfaceDraw {
    std::string name;    ///< file name or "default" (in messages)
    std::string baseDir; ///< directory relative paths are resolved against ("" = working directory)
    std::string mesh = "builtin:box"; ///< "builtin:box", "builtin:torus" or an OBJ path
    SceneDisplacement displacement;
    int isolation = 6;   ///< OpenSubdiv isolation level, 1..10
    /// OpenSubdiv's end caps around extraordinary vertices ("endCaps"): "gregory" (the
    /// default) or "bspline" (BaseSurfaceOptions::gregoryEndCaps): on dense triangle cages at
    /// isolation 2 the base surface builds in 0.76-0.88x the time and holds about 0.65x the
    /// memory, and its normals deviate from isolation 6's about as much (bunny: at most 2.95
    /// against 2.94 degrees; docs/figures.md, production-size cages).
    bool gregoryEndCaps = true;
    int baselineTexels = 0; ///< baseline atlas texels per face edge, 0..kMaxBaselineTexels; 0 = 2^k
    /// The baseline's layout: a chart per face ("faces"), or the mesh's own UVs ("uv": one
    /// square image with as many texels as the faces layout would have, baselineUvSide).
    BaselineLayout baselineLayout = BaselineLayout::Faces;
};
namespace detail {

// The JSON spellings of the enums a scene names.
template <typename E> struct SceneChoice {
    const char* name;
    E value;
};
inline constexpr SceneChoice<Technique> kSceneTechniques[] = {
    {"base", Technique::Base}, {"displaced", Technique::Displaced}, {"baseline", Technique::Baseline}};
inline constexpr SceneChoice<BaselineLayout> kSceneBaselineLayouts[] = {{"faces", BaselineLayout::Faces}, {"uv", BaselineLayout::MeshUv}};
inline constexpr SceneChoice<bool> kSceneEndCaps[] = {{"gregory", true}, {"bspline", false}};
inline constexpr SceneChoice<NormalMode> kSceneNormals[] = {
    {"approximate", NormalMode::Approximate}, {"accurate", NormalMode::Accurate}, {"auto", NormalMode::Auto}};
inline constexpr SceneChoice<MipSelection> kSceneLods[] = {
    {"off", MipSelection::Off}, {"tessfactor", MipSelection::TessFactor}, {"texelratio", MipSelection::TexelRatio}};
inline constexpr SceneChoice<TessMethod> kSceneTessMethods[] = {{"uniform", TessMethod::Uniform},
                                                                {"distance", TessMethod::Distance},
                                                                {"edge", TessMethod::ScreenEdge},
                                                                {"area", TessMethod::ScreenArea}};
inline constexpr SceneChoice<Spacing> kSceneSpacings[] = {{"fractional_even", Spacing::FractionalEven},
                                                          {"integer", Spacing::Integer}};
inline constexpr SceneChoice<TexelFormat> kSceneTexelFormats[] = {{"float", TexelFormat::Float}, {"half", TexelFormat::Half}};
inline constexpr SceneChoice<TexelPath> kSceneTexelPaths[] = {{"buffer", TexelPath::Buffer}, {"image", TexelPath::Image}};

template <typename E, std::size_t N> const char* sceneChoiceName(const SceneChoice<E> (&table)[N], E value) {
    for (const SceneChoice<E>& c : table)
        if (c.value == value) return c.name;
    return "?";
}

// Reads the values of one scene, throwing SceneError "scene '<name>': <path>: <why>".
class SceneReader {
  public:
    using Json = nlohmann::json;
    explicit SceneReader(std::string name) : name_(std::move(name)) {}

    [[noreturn]] void fail(const std::string& path, const std::string& why) const {
        throw SceneError("scene '" + name_ + "': " + (path.empty() ? "" : path + ": ") + why);
    }
    static std::string join(const std::string& path, const char* key) {
        return path.empty() ? std::string(key) : path + "." + key;
    }
    // The value as JSON, cut to about kExcerpt characters: built piece by piece and stopped
    // there, so that a large value is never serialised whole (nor a deep one recursed into).
    static constexpr std::size_t kExcerpt = 80;
    static std::string describe(const Json& j) {
        std::string out;
        excerptTo(j, out, 0);
        return cut(std::move(out));
    }
    // A string from the input (a key, an unknown value), cut to about kExcerpt characters.
    static std::string excerpt(const std::string& s) { return cut(s.size() > kExcerpt + 1 ? s.substr(0, kExcerpt + 1) : s); }

    // j must be an object whose keys are all in `known`; `what` is "key" or "effect".
    void object(const Json& j, const std::string& path, std::initializer_list<const char*> known,
                const char* what = "key") const {
        if (!j.is_object()) fail(path, "expected an object, got " + describe(j));
        for (auto it = j.begin(); it != j.end(); ++it) {
            bool ok = false;
            for (const char* k : known) ok = ok || it.key() == k;
            if (ok) continue;
            std::string list;
            for (const char* k : known) list += (list.empty() ? "" : ", ") + std::string(k);
            fail(path, std::string("unknown ") + what + " '" + excerpt(it.key()) + "' (known: " + list + ")");
        }
    }

    double number(const Json& j, const std::string& path) const {
        if (!j.is_number()) fail(path, "expected a number, got " + describe(j));
        const double x = j.get<double>();
        if (!std::isfinite(x)) fail(path, "must be finite");
        return x;
    }
    int integer(const Json& j, const std::string& path, int lo, int hi) const {
        if (!j.is_number()) fail(path, "expected an integer, got " + describe(j));
        const double x = j.get<double>();
        if (!std::isfinite(x) || x != std::floor(x)) fail(path, "expected an integer, got " + describe(j));
        if (x < lo || x > hi)
            fail(path, describe(j) + " is out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
        return static_cast<int>(x);
    }
    bool boolean(const Json& j, const std::string& path) const {
        if (!j.is_boolean()) fail(path, "expected true or false, got " + describe(j));
        return j.get<bool>();
    }
    std::string string(const Json& j, const std::string& path) const {
        if (!j.is_string()) fail(path, "expected a string, got " + describe(j));
        return j.get<std::string>();
    }
    // Three finite numbers.
    glm::dvec3 vec3(const Json& j, const std::string& path) const {
        if (!j.is_array() || j.size() != 3) fail(path, "expected an array of 3 numbers, got " + describe(j));
        glm::dvec3 v;
        for (int i = 0; i < 3; ++i) v[i] = number(j[static_cast<std::size_t>(i)], path + "[" + std::to_string(i) + "]");
        return v;
    }
    template <typename E, std::size_t N>
    E choice(const Json& j, const std::string& path, const SceneChoice<E> (&table)[N]) const {
        const std::string s = string(j, path);
        std::string list;
        for (const SceneChoice<E>& c : table) {
            if (s == c.name) return c.value;
            list += (list.empty() ? "" : ", ") + std::string(c.name);
        }
        fail(path, "unknown value '" + excerpt(s) + "' (" + list + ")");
    }
    void oneOf(const std::string& s, const std::string& path, std::initializer_list<const char*> known) const {
        std::string list;
        for (const char* k : known) {
            if (s == k) return;
            list += (list.empty() ? "" : ", ") + std::string(k);
        }
        fail(path, "unknown value '" + excerpt(s) + "' (" + list + ")");
    }
    // A path: a string of at most kMaxScenePathLength characters.
    std::string filePath(const Json& j, const std::string& key) const {
        std::string p = string(j, key);
        if (p.size() > kMaxScenePathLength)
            fail(key, "a path of " + std::to_string(p.size()) + " characters, longer than " + std::to_string(kMaxScenePathLength));
        return p;
    }

  private:
    static std::string cut(const std::string& s) { return detail::excerpt(s, kExcerpt); }
    static void excerptTo(const Json& j, std::string& out, int depth) {
        const auto dumpString = [&](const std::string& str) {
            out += Json(str.size() > kExcerpt ? str.substr(0, kExcerpt) : str).dump(-1, ' ', false, Json::error_handler_t::replace);
        };
        if (out.size() > kExcerpt) return;
        if (depth > kMaxSceneJsonDepth) {
            out += "...";
        } else if (j.is_array()) {
            out += '[';
            for (std::size_t i = 0; i < j.size() && out.size() <= kExcerpt; ++i) {
                if (i > 0) out += ',';
                excerptTo(j[i], out, depth + 1);
            }
            out += ']';
        } else if (j.is_object()) {
            out += '{';
            bool first = true;
            for (auto it = j.begin(); it != j.end() && out.size() <= kExcerpt; ++it) {
                if (!first) out += ',';
                first = false;
                dumpString(it.key());
                out += ':';
                excerptTo(it.value(), out, depth + 1);
            }
            out += '}';
        } else if (j.is_string()) {
            dumpString(j.get_ref<const std::string&>());
        } else {
            out += j.dump();
        }
    }
    std::string name_;
};


} // namespace detail

/// The text of the embedded default scene (the box with a pentagon and a triangle, waves).
inline const char* defaultSceneJson() {
    return R"({
  "mesh": "builtin:box",
  "isolation": 6,
  "displacement": {"function": "waves", "scale": 0.07, "k": 5, "filter": "haar"},
  "camera": {"eye": [2.6, 2.0, 3.4], "target": [0, 0, 0], "up": [0, 1, 0], "fovY": 40, "near": 0.05, "far": 100},
  "lights": [
    {"direction": [0.45, 0.8, 0.55], "color": [0.95, 0.92, 0.86]},
    {"direction": [-0.7, 0.15, -0.4], "color": [0.22, 0.26, 0.34]}
  ],
  "ambient": 0.15,
  "albedo": [0.8, 0.78, 0.74],
  "background": [0.0, 0.0, 0.0],
  "resolution": [320, 240],
  "effects": {
    "technique": "displaced",
    "normals": "approximate",
    "lod": "tessfactor",
    "tessellation": {"method": "uniform", "value": 32, "max": 64, "spacing": "fractional_even"}
  }
}
)";
}

/// Parses the JSON of a scene file (a surface scene or a mesostructure scene, scene/meso.h):
/// comments allowed, nesting at most kMaxSceneJsonDepth deep (checked on the text first). Throws
/// SceneError "scene '<name>': invalid JSON: ..." (the parser's message cut to a few hundred
/// characters: it may quote the input).
inline nlohmann::json parseSceneJson(std::string_view text, const std::string& name) {
    using Json = nlohmann::json;
    const detail::SceneReader r(name);
    if (const std::size_t at = detail::jsonTooDeepAt(text, kMaxSceneJsonDepth); at != std::string_view::npos)
        r.fail("", "invalid JSON: arrays and objects nest deeper than " + std::to_string(kMaxSceneJsonDepth) +
                       " levels (at byte " + std::to_string(at) + ")");
    try {
        return Json::parse(text.begin(), text.end(), nullptr, true, /*ignore_comments=*/true);
    } catch (const Json::exception& e) {
        std::string what = e.what();
        if (what.size() > 300) what = what.substr(0, 297) + "...";
        r.fail("", "invalid JSON: " + what);
    }
}

/// Reads a scene file's JSON (parseSceneJson): a regular file of at most kMaxSceneFileBytes.
/// Throws FileError naming the path if it cannot be read, SceneError for its content.
inline nlohmann::json loadSceneJson(const std::string& path) {
    const std::vector<unsigned char> bytes = detail::readFileBytes(path, "scene file", kMaxSceneFileBytes);
    return parseSceneJson(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), path);
}

/// Parses a scene from its JSON document. `name` names the scene in messages (the file name or
/// "default"); relative paths will be resolved against `baseDir`. Throws SceneError (see the
/// top of this file). Files are not opened here (sceneMesh and sceneTiles do that).
inline Scene parseSceneDocument(const nlohmann::json& root, const std::string& name, const std::string& baseDir) {
    using Json = nlohmann::json;
    const detail::SceneReader r(name);
    Scene s;
    s.name = name;
    s.baseDir = baseDir;
    r.object(root, "", {"mesh", "isolation", "endCaps", "displacement", "camera", "lights", "ambient", "albedo", "background",
                        "resolution", "baselineTexels", "baselineLayout", "effects"});
    const auto has = [](const Json& j, const char* key) { return j.contains(key); };
    // Numbers of the draw are only read here; their ranges are surfaceDrawProblem's (below),
    // the rule the renderers apply too.

    if (has(root, "mesh")) {
        s.mesh = r.filePath(root["mesh"], "mesh");
        if (s.mesh.empty()) r.fail("mesh", "empty (give \"builtin:box\", \"builtin:torus\" or an OBJ path)");
        if (s.mesh.rfind("builtin:", 0) == 0) {
            const std::string b = s.mesh.substr(8);
            if (b != "box" && b != "torus")
                r.fail("mesh", "unknown built-in mesh '" + detail::SceneReader::excerpt(b) + "' (known: " + builtin::builtinMeshNames() + ")");
        }
    }
    if (has(root, "isolation")) s.isolation = r.integer(root["isolation"], "isolation", 1, 10);
    if (has(root, "endCaps")) s.gregoryEndCaps = r.choice(root["endCaps"], "endCaps", detail::kSceneEndCaps);

    if (has(root, "displacement")) {
        const Json& d = root["displacement"];
        r.object(d, "displacement",
                 {"function", "height", "tiles", "scale", "offset", "wrap", "k", "mixedSizes", "filter", "sharpBand",
                  "midLevel", "channel", "uv", "mapFilter", "sizes", "sizeTolerance", "allowOverlap"});
        SceneDisplacement& o = s.displacement;
        if (has(d, "function")) {
            o.function = r.string(d["function"], "displacement.function");
            r.oneOf(o.function, "displacement.function", {"waves", "zero"});
        }
        if (has(d, "height")) o.height = r.filePath(d["height"], "displacement.height");
        if (has(d, "tiles")) o.tiles = r.filePath(d["tiles"], "displacement.tiles");
        if (!o.height.empty() && !o.tiles.empty())
            r.fail("displacement", "give either a height image or a tile file, not both");
        if (has(d, "scale")) o.scale = r.number(d["scale"], "displacement.scale");
        if (has(d, "offset")) o.offset = r.number(d["offset"], "displacement.offset");
        if (const std::optional<DrawProblem> p = displacementProblem(o)) r.fail(p->key, p->why);
        if (has(d, "wrap")) o.wrap = r.boolean(d["wrap"], "displacement.wrap");
        if (has(d, "midLevel")) {
            o.midLevel = r.number(d["midLevel"], "displacement.midLevel");
            if (!(std::abs(o.midLevel) <= kMaxDisplacement))
                r.fail("displacement.midLevel", detail::drawNumber(o.midLevel) + " exceeds " + detail::drawNumber(kMaxDisplacement));
        }
        if (has(d, "channel")) o.channel = r.string(d["channel"], "displacement.channel");
        if (has(d, "uv")) {
            o.uv = r.string(d["uv"], "displacement.uv");
            if (!parseUvInterpolation(o.uv))
                r.fail("displacement.uv", "unknown value '" + detail::SceneReader::excerpt(o.uv) + "' (" + uvInterpolationNames() + ")");
        }
        if (has(d, "mapFilter")) {
            o.mapFilter = r.string(d["mapFilter"], "displacement.mapFilter");
            r.oneOf(o.mapFilter, "displacement.mapFilter", {"point", "box", "tent"});
        }
        if (has(d, "sizes")) {
            o.sizes = r.string(d["sizes"], "displacement.sizes");
            r.oneOf(o.sizes, "displacement.sizes", {"uniform", "texels", "error"});
        }
        if (has(d, "sizeTolerance")) {
            o.sizeTolerance = r.number(d["sizeTolerance"], "displacement.sizeTolerance");
            if (!(o.sizeTolerance > 0.0 && o.sizeTolerance <= 1.0))
                r.fail("displacement.sizeTolerance", detail::drawNumber(o.sizeTolerance) + " is not in (0, 1] (the map's height units)");
        }
        if (has(d, "allowOverlap")) o.allowOverlap = r.boolean(d["allowOverlap"], "displacement.allowOverlap");
        if (has(d, "k")) o.k = r.integer(d["k"], "displacement.k", kMinTileLog2, kMaxTileLog2);
        if (has(d, "mixedSizes")) o.mixedSizes = r.boolean(d["mixedSizes"], "displacement.mixedSizes");
        if (o.mixedSizes && o.sizes != "uniform") r.fail("displacement", "give mixedSizes or sizes \"" + o.sizes + "\", not both");
        if (has(d, "filter")) {
            o.filter = r.string(d["filter"], "displacement.filter");
            r.oneOf(o.filter, "displacement.filter", {"haar", "bwavelet"});
        }
        if (has(d, "sharpBand")) {
            o.sharpBand = r.number(d["sharpBand"], "displacement.sharpBand");
            if (!(o.sharpBand >= 0.0 && o.sharpBand <= 0.5))
                r.fail("displacement.sharpBand", detail::drawNumber(o.sharpBand) + " is not in [0, 0.5] (base-face edges; 0: off)");
        }
    }

    if (has(root, "camera")) {
        const Json& c = root["camera"];
        r.object(c, "camera", {"eye", "target", "up", "fovY", "near", "far"});
        Camera& o = s.camera;
        if (has(c, "eye")) o.eye = r.vec3(c["eye"], "camera.eye");
        if (has(c, "target")) o.target = r.vec3(c["target"], "camera.target");
        if (has(c, "up")) o.up = r.vec3(c["up"], "camera.up");
        if (has(c, "fovY")) o.fovYDeg = r.number(c["fovY"], "camera.fovY");
        if (has(c, "near")) o.nearPlane = r.number(c["near"], "camera.near");
        if (has(c, "far")) o.farPlane = r.number(c["far"], "camera.far");
    }

    if (has(root, "lights")) {
        const Json& l = root["lights"];
        if (!l.is_array()) r.fail("lights", "expected an array of lights, got " + detail::SceneReader::describe(l));
        if (l.size() > static_cast<std::size_t>(kMaxLights))
            r.fail("lights", std::to_string(l.size()) + " lights, at most " + std::to_string(kMaxLights));
        s.lights.clear();
        for (std::size_t i = 0; i < l.size(); ++i) {
            const std::string path = "lights[" + std::to_string(i) + "]";
            r.object(l[i], path, {"direction", "color"});
            Light light;
            if (has(l[i], "direction")) light.direction = r.vec3(l[i]["direction"], path + ".direction");
            if (has(l[i], "color")) light.color = r.vec3(l[i]["color"], path + ".color");
            // Already unit length to rounding (as toJson writes it): kept, so that a scene
            // round-trips bit for bit. A zero or overlong one is left for the range rule.
            const double len = glm::length(light.direction);
            if (len > 0.0 && std::isfinite(len) && std::abs(len - 1.0) > 1e-15) light.direction /= len;
            s.lights.push_back(light);
        }
    }
    if (has(root, "ambient")) s.ambient = r.number(root["ambient"], "ambient");
    if (has(root, "albedo")) s.albedo = r.vec3(root["albedo"], "albedo");
    if (has(root, "background")) s.background = r.vec3(root["background"], "background");
    if (has(root, "resolution")) {
        const Json& res = root["resolution"];
        if (!res.is_array() || res.size() != 2)
            r.fail("resolution", "expected [width, height], got " + detail::SceneReader::describe(res));
        // The range is the draw's (kMaxImageSize), checked here too so that the value fits an int.
        s.width = r.integer(res[0], "resolution[0]", 1, kMaxImageSize);
        s.height = r.integer(res[1], "resolution[1]", 1, kMaxImageSize);
    }
    if (has(root, "baselineTexels"))
        s.baselineTexels = r.integer(root["baselineTexels"], "baselineTexels", 0, kMaxBaselineTexels);
    if (has(root, "baselineLayout")) s.baselineLayout = r.choice(root["baselineLayout"], "baselineLayout", detail::kSceneBaselineLayouts);

    if (has(root, "effects")) {
        const Json& e = root["effects"];
        r.object(e, "effects", {"technique", "normals", "autoTolerance", "lod", "tessellation", "wireframe", "texelFormat", "texelPath"},
                 "effect");
        SurfaceEffects& o = s.effects;
        if (has(e, "technique")) o.technique = r.choice(e["technique"], "effects.technique", detail::kSceneTechniques);
        if (has(e, "normals")) o.normals = r.choice(e["normals"], "effects.normals", detail::kSceneNormals);
        if (has(e, "autoTolerance")) o.autoToleranceDeg = r.number(e["autoTolerance"], "effects.autoTolerance");
        if (has(e, "lod")) {
            // "seed004": the texel-ratio rule's former name, still read (written as "texelratio").
            const bool formerName = e["lod"].is_string() && e["lod"].get<std::string>() == "seed004";
            o.lod = formerName ? MipSelection::TexelRatio : r.choice(e["lod"], "effects.lod", detail::kSceneLods);
        }
        if (has(e, "wireframe")) o.wireframe = r.boolean(e["wireframe"], "effects.wireframe");
        if (has(e, "texelFormat")) o.texelFormat = r.choice(e["texelFormat"], "effects.texelFormat", detail::kSceneTexelFormats);
        if (has(e, "texelPath")) o.texelPath = r.choice(e["texelPath"], "effects.texelPath", detail::kSceneTexelPaths);
        if (has(e, "tessellation")) {
            const Json& t = e["tessellation"];
            r.object(t, "effects.tessellation", {"method", "value", "max", "spacing"});
            if (has(t, "method"))
                o.tessMethod = r.choice(t["method"], "effects.tessellation.method", detail::kSceneTessMethods);
            if (has(t, "value")) o.tessValue = r.number(t["value"], "effects.tessellation.value");
            if (has(t, "max")) o.maxFactor = r.number(t["max"], "effects.tessellation.max");
            if (has(t, "spacing"))
                o.spacing = r.choice(t["spacing"], "effects.tessellation.spacing", detail::kSceneSpacings);
        }
    }
    // One rule for the scene file and the renderers (surface/draw.h), with the key named.
    if (const std::optional<DrawProblem> p = surfaceDrawProblem(s)) r.fail(p->key, p->why);
    return s;
}

/// Parses a scene from JSON text (parseSceneJson, then parseSceneDocument). Throws SceneError.
inline Scene parseScene(std::string_view json, const std::string& name, const std::string& baseDir) {
    return parseSceneDocument(parseSceneJson(json, name), name, baseDir);
}

/// Reads and parses a scene file; relative paths in it resolve against its directory.
/// Throws FileError naming the path if it cannot be read (not a regular file, or above
/// kMaxSceneFileBytes), SceneError (named by the path) for its content.
inline Scene loadScene(const std::string& path) {
    return parseSceneDocument(loadSceneJson(path), path, std::filesystem::path(path).parent_path().string());
}

/// The embedded default scene.
inline Scene defaultScene() { return parseScene(defaultSceneJson(), "default", ""); }

/// The scene as JSON (every key, paths as written); parseScene of it gives the scene back.
inline std::string toJson(const Scene& s) {
    using Json = nlohmann::ordered_json;
    const auto v3 = [](const glm::dvec3& v) { return Json::array({v.x, v.y, v.z}); };
    Json j;
    j["mesh"] = s.mesh;
    j["isolation"] = s.isolation;
    j["endCaps"] = detail::sceneChoiceName(detail::kSceneEndCaps, s.gregoryEndCaps);
    const SceneDisplacement& d = s.displacement;
    j["displacement"] = {{"function", d.function}, {"height", d.height}, {"tiles", d.tiles},
                         {"scale", d.scale},       {"offset", d.offset}, {"wrap", d.wrap},
                         {"k", d.k},               {"mixedSizes", d.mixedSizes}, {"filter", d.filter},
                         {"sharpBand", d.sharpBand}, {"midLevel", d.midLevel}, {"channel", d.channel},
                         {"uv", d.uv},             {"mapFilter", d.mapFilter}, {"sizes", d.sizes},
                         {"sizeTolerance", d.sizeTolerance}, {"allowOverlap", d.allowOverlap}};
    const Camera& c = s.camera;
    j["camera"] = {{"eye", v3(c.eye)},       {"target", v3(c.target)}, {"up", v3(c.up)},
                   {"fovY", c.fovYDeg},      {"near", c.nearPlane},    {"far", c.farPlane}};
    Json lights = Json::array();
    for (const Light& l : s.lights) lights.push_back({{"direction", v3(l.direction)}, {"color", v3(l.color)}});
    j["lights"] = std::move(lights);
    j["ambient"] = s.ambient;
    j["albedo"] = v3(s.albedo);
    j["background"] = v3(s.background);
    j["resolution"] = Json::array({s.width, s.height});
    j["baselineTexels"] = s.baselineTexels;
    j["baselineLayout"] = detail::sceneChoiceName(detail::kSceneBaselineLayouts, s.baselineLayout);
    const SurfaceEffects& e = s.effects;
    j["effects"] = {{"technique", detail::sceneChoiceName(detail::kSceneTechniques, e.technique)},
                    {"normals", detail::sceneChoiceName(detail::kSceneNormals, e.normals)},
                    {"autoTolerance", e.autoToleranceDeg},
                    {"lod", detail::sceneChoiceName(detail::kSceneLods, e.lod)},
                    {"tessellation",
                     {{"method", detail::sceneChoiceName(detail::kSceneTessMethods, e.tessMethod)},
                      {"value", e.tessValue},
                      {"max", e.maxFactor},
                      {"spacing", detail::sceneChoiceName(detail::kSceneSpacings, e.spacing)}}},
                    {"wireframe", e.wireframe},
                    {"texelFormat", detail::sceneChoiceName(detail::kSceneTexelFormats, e.texelFormat)},
                    {"texelPath", detail::sceneChoiceName(detail::kSceneTexelPaths, e.texelPath)}};
    // Paths need not be UTF-8; JSON must be: invalid bytes become U+FFFD.
    return j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

/// `path` resolved against the scene's directory (absolute paths and an empty baseDir leave
/// it as it is).
inline std::string resolveScenePath(const Scene& scene, const std::string& path) {
    const std::filesystem::path p(path);
    if (p.is_absolute() || scene.baseDir.empty()) return path;
    return (std::filesystem::path(scene.baseDir) / p).string();
}

} // namespace dispmap
