#pragma once
// Mesostructure scene files (JSON), rendered by `dispmap render` with the fragment-shader
// marcher (backend_vulkan MesoRenderer): a plane tiled with a height-field mesostructure.
//
//   {"mesostructure": {"height": "bricks.png", "size": 64, "layers": 16, "depth": 14,
//                      "cones": "4x1", "block": 4},          (or "function": "grating")
//    "camera": {"eye": [0.3, -1.2, 0.7], "target": [0, 0, 0], "fov": 45},
//    "light": [0.4, 0.3, 0.8], "resolution": [320, 240], "tile": 0.5, "slab": 0.06,
//    "effects": {"technique": "ddm", "quadrics": true, "iterations": 128, "exitRule": 1,
//                "eps": -1, "linear": 32, "binary": 6, "shadows": false}}
//
// Effects, and only those: the maps the technique reads are the only maps built (a relief
// scene builds no distance map and no DDM; shadow cones only with "shadows"), and the
// technique's marcher is the only one compiled into the pipeline (specialisation constants).
// Every key is optional; unknown keys, bad values and missing files are ArgumentError /
// FileError naming the scene and the key.
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "dispmap/io/png.h"
#include "dispmap/meso/march.h"

namespace dispmap {

struct MesoSceneDesc {
    std::string name;
    std::string heightImage;        ///< image path (resolved against the scene's folder); empty: the function
    std::string function = "grating";
    int size = 64, layers = 16;     ///< texels per side after a box filter (0: the image's), voxel layers
    double depth = -1;              ///< voxels of white (default: 7/8 of the layers)
    ConeSet cones{4, 1, false, false};
    int block = 4;
    glm::dvec3 eye{0.35, -1.3, 0.75}, target{0.0, 0.0, 0.0}, light{0.4, 0.3, 0.8};
    double fov = 45, tile = 0.5, slab = 0.06;
    int width = 320, height = 240;
    MesoTechnique technique;
    bool shadows = false;
};

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

/// The image box-filtered to size x size (integer factors; the remainder is cut).
inline HeightImage downsampleHeightImage(const HeightImage& img, int size) {
    if (size < 2) throw ArgumentError("downsampleHeightImage: size " + std::to_string(size) + " is below 2");
    const int fx = img.width / size, fy = img.height / size;
    if (fx < 1 || fy < 1)
        throw ArgumentError("downsampleHeightImage: size " + std::to_string(size) + ": the image (" + std::to_string(img.width) + " x " +
                            std::to_string(img.height) + ") is smaller");
    HeightImage small;
    small.width = small.height = size;
    small.values.assign(static_cast<std::size_t>(size) * static_cast<std::size_t>(size), 0.0f);
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            double sum = 0;
            for (int b = 0; b < fy; ++b)
                for (int a = 0; a < fx; ++a) sum += static_cast<double>(img.at(x * fx + a, y * fy + b));
            small.values[static_cast<std::size_t>(y * size + x)] = static_cast<float>(sum / (fx * fy));
        }
    return small;
}

namespace detail {
inline void mesoKeys(const nlohmann::json& j, const std::string& scene, const std::string& where, std::initializer_list<const char*> keys) {
    if (!j.is_object()) throw ArgumentError(scene + ": '" + where + "' must be an object");
    for (const auto& [k, v] : j.items()) {
        (void)v;
        bool known = false;
        for (const char* key : keys) known = known || k == key;
        if (!known) throw ArgumentError(scene + ": unknown key '" + (where.empty() ? k : where + "." + k) + "'");
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
    }
    return static_cast<T>(d);
}
inline glm::dvec3 mesoVec3(const nlohmann::json& j, const char* key, glm::dvec3 fallback, const std::string& scene, const std::string& where) {
    if (!j.contains(key)) return fallback;
    const nlohmann::json& v = j[key];
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
        throw ArgumentError(scene + ": '" + where + key + "' must be [x, y, z]");
    const glm::dvec3 r(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
    if (!std::isfinite(r.x + r.y + r.z)) throw ArgumentError(scene + ": '" + where + key + "' is not finite");
    return r;
}
} // namespace detail

/// Whether a scene file's JSON is a mesostructure scene (it has the "mesostructure" key).
inline bool isMesoScene(const nlohmann::json& j) { return j.is_object() && j.contains("mesostructure"); }

inline MesoSceneDesc parseMesoScene(const nlohmann::json& j, const std::string& name, const std::string& baseDir) {
    using namespace detail;
    MesoSceneDesc s;
    s.name = name;
    mesoKeys(j, name, "", {"mesostructure", "camera", "light", "resolution", "tile", "slab", "effects"});
    const nlohmann::json& m = j["mesostructure"];
    mesoKeys(m, name, "mesostructure", {"height", "function", "size", "layers", "depth", "cones", "block"});
    if (m.contains("height")) {
        if (!m["height"].is_string()) throw ArgumentError(name + ": 'mesostructure.height' must be a file name");
        const std::filesystem::path p(m["height"].get<std::string>());
        s.heightImage = p.is_absolute() || baseDir.empty() ? p.string() : (std::filesystem::path(baseDir) / p).string();
    }
    if (m.contains("function")) {
        if (!m["function"].is_string()) throw ArgumentError(name + ": 'mesostructure.function' must be a name");
        s.function = m["function"].get<std::string>();
    }
    s.size = mesoNumber(m, "size", s.heightImage.empty() ? 64 : 0, name, "mesostructure.");
    s.layers = mesoNumber(m, "layers", s.layers, name, "mesostructure.");
    s.depth = mesoNumber(m, "depth", s.depth, name, "mesostructure.");
    s.block = mesoNumber(m, "block", s.block, name, "mesostructure.");
    if (m.contains("cones")) {
        if (!m["cones"].is_string()) throw ArgumentError(name + ": 'mesostructure.cones' must be \"MxN\" or \"isotropic\"");
        try {
            s.cones = parseConeSet(m["cones"].get<std::string>());
        } catch (const ArgumentError& e) {
            throw ArgumentError(name + ": 'mesostructure.cones': " + e.what());
        }
    }
    if (j.contains("camera")) {
        const nlohmann::json& c = j["camera"];
        mesoKeys(c, name, "camera", {"eye", "target", "fov"});
        s.eye = mesoVec3(c, "eye", s.eye, name, "camera.");
        s.target = mesoVec3(c, "target", s.target, name, "camera.");
        s.fov = mesoNumber(c, "fov", s.fov, name, "camera.");
    }
    s.light = mesoVec3(j, "light", s.light, name, "");
    if (j.contains("resolution")) {
        const nlohmann::json& r = j["resolution"];
        if (!r.is_array() || r.size() != 2 || !r[0].is_number_integer() || !r[1].is_number_integer())
            throw ArgumentError(name + ": 'resolution' must be [width, height]");
        s.width = r[0].get<int>();
        s.height = r[1].get<int>();
        if (s.width < 1 || s.height < 1 || s.width > 4096 || s.height > 4096)
            throw ArgumentError(name + ": 'resolution' " + std::to_string(s.width) + " x " + std::to_string(s.height) + " is out of range (1 .. 4096)");
    }
    s.tile = mesoNumber(j, "tile", s.tile, name, "");
    s.slab = mesoNumber(j, "slab", s.slab, name, "");
    if (!(s.tile > 0) || !(s.slab > 0)) throw ArgumentError(name + ": 'tile' and 'slab' must be > 0");
    if (j.contains("effects")) {
        const nlohmann::json& e = j["effects"];
        mesoKeys(e, name, "effects", {"technique", "quadrics", "iterations", "exitRule", "eps", "linear", "binary", "shadows"});
        MesoTechnique& t = s.technique;
        if (e.contains("technique")) {
            const std::string k = e["technique"].is_string() ? e["technique"].get<std::string>() : "";
            if (k == "ddm") t.method = MesoMethod::Ddm;
            else if (k == "distance_map") t.method = MesoMethod::DistanceMap;
            else if (k == "relief") t.method = MesoMethod::Relief;
            else if (k == "pom") t.method = MesoMethod::Pom;
            else throw ArgumentError(name + ": unknown 'effects.technique' '" + k + "' (ddm, distance_map, relief, pom)");
        }
        const auto flag = [&](const char* key, bool fallback) {
            if (!e.contains(key)) return fallback;
            if (!e[key].is_boolean()) throw ArgumentError(name + ": 'effects." + key + "' must be true or false");
            return e[key].get<bool>();
        };
        t.quadrics = flag("quadrics", t.quadrics);
        s.shadows = flag("shadows", s.shadows);
        t.iterations = mesoNumber(e, "iterations", t.iterations, name, "effects.");
        t.exitRule = mesoNumber(e, "exitRule", t.exitRule, name, "effects.");
        t.eps = mesoNumber(e, "eps", t.eps, name, "effects.");
        t.linear = mesoNumber(e, "linear", t.linear, name, "effects.");
        t.binary = mesoNumber(e, "binary", t.binary, name, "effects.");
        if (t.iterations < 1 || t.linear < 1 || t.binary < 0 || (t.exitRule != 0 && t.exitRule != 1))
            throw ArgumentError(name + ": 'effects' iterations and linear must be >= 1, binary >= 0, exitRule 0 or 1");
    }
    if (s.layers < 2 || s.layers > kMaxMesoLayers) throw ArgumentError(name + ": 'mesostructure.layers' out of range (2 .. 256)");
    if (s.size != 0 && (s.size < 2 || s.size > kMaxMesoSize))
        throw ArgumentError(name + ": 'mesostructure.size' " + std::to_string(s.size) + " out of range (2 .. " + std::to_string(kMaxMesoSize) + ")");
    return s;
}

/// The scene's height field (the image box-filtered to `size`, or the function), and the maps
/// its effects need (mesoMapOptionsFor): nothing else is built.
inline MesoMaps buildMesoSceneMaps(const MesoSceneDesc& s) {
    MesoHeightField field;
    const double depth = s.depth > 0 ? s.depth : 0.875 * s.layers;
    if (!s.heightImage.empty()) {
        HeightImage img = readHeightPng(s.heightImage);
        if (s.size > 0 && s.size != img.width) img = downsampleHeightImage(img, s.size);
        field = mesoHeightFieldFromImage(img, s.layers, depth);
    } else {
        field = mesoFunctionField(s.function, s.size, s.layers);
    }
    MesoMapOptions o = mesoMapOptionsFor(s.technique, s.shadows, s.cones);
    o.block = s.block;
    return buildMesoMaps(field, o);
}

} // namespace dispmap
