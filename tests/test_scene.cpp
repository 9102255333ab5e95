// Scene files (scene.h) and the built-in meshes (builtin.h): defaults, a full scene, the JSON
// round trip, every rejected input with the key path in its message, paths resolved against
// the scene's directory, tiles from each source, mixed tile sizes.
#include <catch2/catch.hpp>

#include "test_files.h"
#include "test_support.h"

#include <exception>
#include <set>
#include <string>
#include <vector>

#include "dispmap/surface/builtin.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/scene/build.h"
#include "dispmap/scene/surface.h"
#include "dispmap/scene/scene.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_scene {

using namespace dispmap;

namespace {
struct TempDir : dmtest::TempDir {
    TempDir() : dmtest::TempDir("dispmap_scene_test_") {}
};

void writeText(const std::string& path, const std::string& text) {
    dmtest::writeBytes(path, std::vector<unsigned char>(text.begin(), text.end()));
}

// The message of the E that f throws, or a note that none (or another exception) was thrown.
template <typename E, typename F> std::string messageOf(F&& f) {
    try {
        f();
    } catch (const E& e) {
        return e.what();
    } catch (const std::exception& e) {
        return std::string("<another exception: ") + e.what() + ">";
    }
    return "<nothing thrown>";
}
#define CHECK_THROWS_MSG(expr, E, matcher) CHECK_THAT(messageOf<E>([&] { (void)(expr); }), matcher)

// Every field of two scenes equal (light directions to rounding: they are normalised again).
void checkSame(const Scene& a, const Scene& b) {
    CHECK(a.mesh == b.mesh);
    CHECK(a.isolation == b.isolation);
    const SceneDisplacement &da = a.displacement, &db = b.displacement;
    CHECK(da.function == db.function);
    CHECK(da.height == db.height);
    CHECK(da.tiles == db.tiles);
    CHECK(da.scale == db.scale);
    CHECK(da.offset == db.offset);
    CHECK(da.wrap == db.wrap);
    CHECK(da.k == db.k);
    CHECK(da.mixedSizes == db.mixedSizes);
    CHECK(da.midLevel == db.midLevel);
    CHECK(da.channel == db.channel);
    CHECK(da.uv == db.uv);
    CHECK(da.mapFilter == db.mapFilter);
    CHECK(da.sizes == db.sizes);
    CHECK(da.sizeTolerance == db.sizeTolerance);
    CHECK(da.allowOverlap == db.allowOverlap);
    CHECK(da.filter == db.filter);
    CHECK(da.sharpBand == db.sharpBand);
    CHECK(a.camera.eye == b.camera.eye);
    CHECK(a.camera.target == b.camera.target);
    CHECK(a.camera.up == b.camera.up);
    CHECK(a.camera.fovYDeg == b.camera.fovYDeg);
    CHECK(a.camera.nearPlane == b.camera.nearPlane);
    CHECK(a.camera.farPlane == b.camera.farPlane);
    REQUIRE(a.lights.size() == b.lights.size());
    for (std::size_t i = 0; i < a.lights.size(); ++i) {
        CHECK(glm::length(a.lights[i].direction - b.lights[i].direction) < 1e-15);
        CHECK(a.lights[i].color == b.lights[i].color);
    }
    CHECK(a.ambient == b.ambient);
    CHECK(a.albedo == b.albedo);
    CHECK(a.background == b.background);
    CHECK(a.width == b.width);
    CHECK(a.height == b.height);
    CHECK(a.baselineTexels == b.baselineTexels);
    CHECK(a.baselineLayout == b.baselineLayout);
    CHECK(a.gregoryEndCaps == b.gregoryEndCaps);
    const SurfaceEffects &ea = a.effects, &eb = b.effects;
    CHECK(ea.technique == eb.technique);
    CHECK(ea.normals == eb.normals);
    CHECK(ea.autoToleranceDeg == eb.autoToleranceDeg);
    CHECK(ea.lod == eb.lod);
    CHECK(ea.tessMethod == eb.tessMethod);
    CHECK(ea.tessValue == eb.tessValue);
    CHECK(ea.maxFactor == eb.maxFactor);
    CHECK(ea.spacing == eb.spacing);
    CHECK(ea.wireframe == eb.wireframe);
    CHECK(ea.texelFormat == eb.texelFormat);
    CHECK(ea.texelPath == eb.texelPath);
}

const char* kFullScene = R"({
  // every key, none at its default
  "mesh": "builtin:torus", "isolation": 4, "endCaps": "bspline",
  "displacement": {"function": "zero", "height": "", "tiles": "", "scale": 0.25, "offset": -0.5, "wrap": true,
                   "k": 3, "mixedSizes": true, "filter": "bwavelet", "sharpBand": 0.125},
  "camera": {"eye": [1, 2, 3], "target": [0.5, 0, -1], "up": [0, 0, 1], "fovY": 55.5, "near": 0.1, "far": 20},
  "lights": [{"direction": [0, 3, 4], "color": [0.5, 0.25, 2]}, {"direction": [-1, 0, 0]}, {}],
  "ambient": 0.3, "albedo": [0.1, 0.2, 0.3], "background": [1, 0.5, 0],
  "resolution": [64, 4096], "baselineTexels": 17, "baselineLayout": "uv",
  "effects": {"technique": "baseline", "normals": "auto", "autoTolerance": 0.5, "lod": "texelratio",
              "tessellation": {"method": "area", "value": 12.5, "max": 32, "spacing": "integer"}, "wireframe": true,
              "texelFormat": "half", "texelPath": "image"}
})";
} // namespace

TEST_CASE("scene: the default scene", "[scene]") {
    const Scene s = defaultScene();
    CHECK(s.name == "default");
    CHECK(s.baseDir.empty());
    CHECK(s.mesh == "builtin:box");
    CHECK(s.displacement.function == "waves");
    CHECK(s.displacement.scale == 0.07);
    CHECK(s.displacement.k == 5);
    CHECK(s.displacement.height.empty());
    CHECK(s.displacement.tiles.empty());
    CHECK(s.width == 320);
    CHECK(s.height == 240);
    CHECK(s.isolation == 6);
    CHECK(s.effects.technique == Technique::Displaced);
    CHECK(s.effects.normals == NormalMode::Approximate);
    CHECK(s.effects.lod == MipSelection::TessFactor);
    CHECK(s.effects.tessMethod == TessMethod::Uniform);
    CHECK(s.effects.tessValue == 32);
    CHECK(s.effects.maxFactor == 64);
    CHECK(s.effects.spacing == Spacing::FractionalEven);
    REQUIRE(!s.lights.empty());
    for (const Light& l : s.lights) CHECK(glm::length(l.direction) == Approx(1.0).margin(1e-15));
    // The camera frames the box: every point of the displaced surface projects inside the
    // central 90 % of the image, and the surface spans at least half of its height.
    const ControlMesh mesh = sceneMesh(s);
    CHECK(mesh.ptexFaceCount() == 21);
    BuildReport rep;
    const TileSet tiles = sceneTiles(s, mesh, &rep);
    CHECK(tiles.tileCount() == 21);
    CHECK(rep.sweeps > 0);
    {
        const BaseSurface base(mesh);
        const DisplacedSurface ds(base, tiles);
        const glm::dvec3 f = glm::normalize(s.camera.target - s.camera.eye);
        const glm::dvec3 r = glm::normalize(glm::cross(f, s.camera.up)), up = glm::cross(r, f);
        const double ty = std::tan(s.camera.fovYDeg * 3.14159265358979323846 / 360.0);
        const double tx = ty * s.width / s.height;
        double yLo = 1, yHi = -1;
        for (int face = 0; face < base.faceCount(); ++face)
            for (int j = 0; j <= 8; ++j)
                for (int i = 0; i <= 8; ++i) {
                    const glm::dvec3 d =
                        ds.evaluate<double>(face, i / 8.0, j / 8.0, NormalMode::Approximate).position - s.camera.eye;
                    const double z = glm::dot(d, f), x = glm::dot(d, r) / z / tx, y = glm::dot(d, up) / z / ty;
                    CHECK(z > s.camera.nearPlane);
                    CHECK(z < s.camera.farPlane);
                    CHECK(std::abs(x) < 0.9);
                    CHECK(std::abs(y) < 0.9);
                    yLo = std::min(yLo, y);
                    yHi = std::max(yHi, y);
                }
        CHECK(yHi - yLo > 1.0);
    }
    // An empty object is the struct defaults, which differ from the default scene's camera.
    const Scene e = parseScene("{}", "empty", "");
    CHECK(e.lights.size() == 1);
    CHECK(e.camera.eye == glm::dvec3(0, 0, 5));

    // Same tiles as the demo builds (waves at scale 0.07 = defaultDisplacement exactly).
    const TileSet demo = buildTiles(mesh, uniformTileSizes(mesh, 5), builtin::defaultDisplacement);
    for (std::size_t t = 0; t < tiles.tiles.size(); ++t) CHECK(tiles.tiles[t].coefficients == demo.tiles[t].coefficients);
}

TEST_CASE("scene: every key parsed, and toJson round-trips", "[scene]") {
    const Scene s = parseScene(kFullScene, "full.json", "/somewhere");
    CHECK(s.name == "full.json");
    CHECK(s.baseDir == "/somewhere");
    CHECK(s.mesh == "builtin:torus");
    CHECK(s.isolation == 4);
    CHECK(s.displacement.function == "zero");
    CHECK(s.displacement.scale == 0.25);
    CHECK(s.displacement.offset == -0.5);
    CHECK(s.displacement.wrap);
    CHECK(s.displacement.k == 3);
    CHECK(s.displacement.mixedSizes);
    CHECK(s.displacement.filter == "bwavelet");
    CHECK(s.displacement.sharpBand == 0.125);
    CHECK(SceneSurface::displacedOptions(s).sharpBand == 0.125);
    CHECK(s.camera.eye == glm::dvec3(1, 2, 3));
    CHECK(s.camera.target == glm::dvec3(0.5, 0, -1));
    CHECK(s.camera.up == glm::dvec3(0, 0, 1));
    CHECK(s.camera.fovYDeg == 55.5);
    CHECK(s.camera.nearPlane == 0.1);
    CHECK(s.camera.farPlane == 20);
    REQUIRE(s.lights.size() == 3);
    CHECK(s.lights[0].direction == glm::dvec3(0, 0.6, 0.8));
    CHECK(s.lights[0].color == glm::dvec3(0.5, 0.25, 2));
    CHECK(s.lights[1].direction == glm::dvec3(-1, 0, 0));
    CHECK(s.lights[1].color == glm::dvec3(1));
    CHECK(s.lights[2].direction == glm::dvec3(0, 0, 1));
    CHECK(s.ambient == 0.3);
    CHECK(s.albedo == glm::dvec3(0.1, 0.2, 0.3));
    CHECK(s.background == glm::dvec3(1, 0.5, 0));
    CHECK(s.width == 64);
    CHECK(s.height == 4096);
    CHECK(s.baselineTexels == 17);
    CHECK(s.baselineLayout == BaselineLayout::MeshUv);
    CHECK(!s.gregoryEndCaps);
    CHECK(s.effects.technique == Technique::Baseline);
    CHECK(s.effects.normals == NormalMode::Auto);
    CHECK(s.effects.autoToleranceDeg == 0.5);
    CHECK(s.effects.lod == MipSelection::TexelRatio);
    // The rule's former name in older scene files still reads, and is written by its new one.
    const Scene former = parseScene(R"({"effects": {"lod": "seed004"}})", "former.json", "");
    CHECK(former.effects.lod == MipSelection::TexelRatio);
    CHECK(toJson(former).find("\"texelratio\"") != std::string::npos);
    CHECK(s.effects.tessMethod == TessMethod::ScreenArea);
    CHECK(s.effects.tessValue == 12.5);
    CHECK(s.effects.maxFactor == 32);
    CHECK(s.effects.spacing == Spacing::Integer);
    CHECK(s.effects.wireframe);
    CHECK(s.effects.texelFormat == TexelFormat::Half);
    CHECK(s.effects.texelPath == TexelPath::Image);

    // The map keys, none at its default (sizes other than "uniform" cannot go with mixedSizes).
    const Scene maps = parseScene(R"({"displacement": {"height": "h.<UDIM>.exr", "midLevel": 0.5, "channel": "G", "uv": "corners+1",
                                                       "mapFilter": "tent", "sizes": "error", "sizeTolerance": 0.125,
                                                       "allowOverlap": true}})",
                                  "maps.json", "");
    CHECK(maps.displacement.midLevel == 0.5);
    CHECK(maps.displacement.channel == "G");
    CHECK(maps.displacement.uv == "corners+1");
    CHECK(maps.displacement.mapFilter == "tent");
    CHECK(maps.displacement.sizes == "error");
    CHECK(maps.displacement.sizeTolerance == 0.125);
    CHECK(maps.displacement.allowOverlap);
    for (const Scene& x : {s, maps, defaultScene(), parseScene("{}", "empty", "")}) {
        const std::string text = toJson(x);
        INFO(text);
        const Scene y = parseScene(text, x.name, x.baseDir);
        checkSame(x, y);
        CHECK(toJson(y) == text);
    }
    // Every enum value survives the trip.
    for (const char* m : {"uniform", "distance", "edge", "area"})
        for (const char* t : {"base", "displaced", "baseline"}) {
            const std::string j = std::string(R"({"effects": {"technique": ")") + t +
                                  R"(", "tessellation": {"method": ")" + m + R"("}}})";
            const Scene a = parseScene(j, "enum", "");
            CHECK(std::string(toString(a.effects.tessMethod)) == m);
            CHECK(std::string(toString(a.effects.technique)) == t);
            checkSame(a, parseScene(toJson(a), "enum", ""));
        }
}

TEST_CASE("scene: rejected inputs name the scene and the key", "[scene][errors]") {
    using Row = std::pair<const char*, const char*>;
    const std::vector<Row> rows = {
        {R"({"mesh": "builtin:box",})", "scene 'bad.json': invalid JSON: [json.exception.parse_error"},
        {R"({"mesh": )", "invalid JSON"},
        {"", "invalid JSON"},
        {"[1, 2]", "scene 'bad.json': expected an object"},
        {R"({"meshes": "x"})", "scene 'bad.json': unknown key 'meshes' (known: mesh, isolation,"},
        {R"({"mesh": 3})", "scene 'bad.json': mesh: expected a string, got 3"},
        {R"({"mesh": ""})", "mesh: empty"},
        {R"({"mesh": "builtin:teapot"})", "mesh: unknown built-in mesh 'teapot' (known: box, torus)"},
        {R"({"isolation": 0})", "isolation: 0 is out of range [1, 10]"},
        {R"({"isolation": 11})", "isolation: 11 is out of range [1, 10]"},
        {R"({"isolation": 6.5})", "isolation: expected an integer, got 6.5"},
        {R"({"isolation": "6"})", "isolation: expected an integer"},
        {R"({"displacement": {"k": 0}})", "displacement.k: 0 is out of range [1, 8]"},
        {R"({"displacement": {"k": 11}})", "displacement.k: 11 is out of range"},
        {R"({"displacement": {"kk": 1}})", "displacement: unknown key 'kk' (known: function, height, tiles,"},
        {R"({"displacement": {"function": "noise"}})", "displacement.function: unknown value 'noise' (waves, zero)"},
        {R"({"displacement": {"filter": "box"}})", "displacement.filter: unknown value 'box' (haar, bwavelet)"},
        {R"({"displacement": {"uv": "smoothest"}})", "displacement.uv: unknown value 'smoothest'"},
        {R"({"displacement": {"mapFilter": "gauss"}})", "displacement.mapFilter: unknown value 'gauss' (point, box, tent)"},
        {R"({"displacement": {"sizes": "texels", "mixedSizes": true}})", "give mixedSizes or sizes \"texels\", not both"},
        {R"({"displacement": {"sizes": "error", "mixedSizes": true}})", "give mixedSizes or sizes \"error\", not both"},
        {R"({"displacement": {"sizeTolerance": 0}})", "displacement.sizeTolerance: 0 is not in (0, 1]"},
        {R"({"displacement": {"sizeTolerance": 1.5}})", "displacement.sizeTolerance: 1.5 is not in (0, 1]"},
        {R"({"displacement": {"midLevel": 1e7}})", "displacement.midLevel: "},
        {R"({"displacement": {"sharpBand": 0.6}})", "displacement.sharpBand: 0.6 is not in [0, 0.5]"},
        {R"({"displacement": {"sharpBand": -0.1}})", "displacement.sharpBand: -0.1 is not in [0, 0.5]"},
        // nlohmann refuses numbers that overflow a double (no infinities from JSON).
        {R"({"displacement": {"scale": 1e999}})", "invalid JSON: [json.exception.out_of_range.406] number overflow"},
        {R"({"displacement": {"offset": -1e999}})", "number overflow parsing '-1e999'"},
        {R"({"displacement": {"wrap": 1}})", "displacement.wrap: expected true or false"},
        {R"({"displacement": {"height": "h.png", "tiles": "t.dmt"}})", "displacement: give either a height image or a tile file"},
        {R"({"displacement": 5})", "displacement: expected an object"},
        {R"({"camera": {"eye": [1, 2]}})", "camera.eye: expected an array of 3 numbers"},
        {R"({"camera": {"eye": [1, 2, "3"]}})", "camera.eye[2]: expected a number"},
        {R"({"camera": {"eye": [1, 2, 3], "target": [1, 2, 3]}})", "camera: eye and target are the same point"},
        {R"({"camera": {"eye": [0, 5, 0]}})", "camera.up: is parallel to the view direction"},
        {R"({"camera": {"up": [0, 0, 0]}})", "camera.up: is the zero vector"},
        {R"({"camera": {"fovY": 0}})", "camera.fovY: 0 is out of range (must be > 0)"},
        {R"({"camera": {"fovY": 180}})", "camera.fovY: 180 is out of range (must be < 180)"},
        {R"({"camera": {"near": 0}})", "camera.near: 0 is out of range (must be > 0)"},
        {R"({"camera": {"near": 5, "far": 2}})", "camera.far: must be greater than camera.near"},
        {R"({"camera": {"fov": 30}})", "camera: unknown key 'fov' (known: eye, target, up, fovY, near, far)"},
        {R"({"lights": {"direction": [0, 0, 1]}})", "lights: expected an array of lights"},
        {R"({"lights": [{"direction": [0, 0, 0]}]})", "lights[0].direction: is the zero vector"},
        {R"({"lights": [{}, {"color": [1, -1, 1]}]})", "lights[1].color[1]: -1 is out of range (must be >= 0)"},
        {R"({"lights": [{"dir": [0, 0, 1]}]})", "lights[0]: unknown key 'dir' (known: direction, color)"},
        {R"({"lights": [{},{},{},{},{},{},{},{},{}]})", "lights: 9 lights, at most 8"},
        {R"({"ambient": -0.1})", "ambient: -0.1 is out of range (must be >= 0)"},
        {R"({"albedo": [0.5, 1.5, 0.5]})", "albedo[1]: 1.5 is out of range (must be <= 1)"},
        {R"({"background": [0, 0]})", "background: expected an array of 3 numbers"},
        {R"({"resolution": [0, 240]})", "resolution[0]: 0 is out of range [1, 4096]"},
        {R"({"resolution": [320, 4097]})", "resolution[1]: 4097 is out of range [1, 4096]"},
        {R"({"resolution": 320})", "resolution: expected [width, height]"},
        {R"({"baselineTexels": -1})", "baselineTexels: -1 is out of range [0, 1024]"},
        {R"({"baselineTexels": 1025})", "baselineTexels: 1025 is out of range [0, 1024]"},
        {R"({"baselineLayout": "atlas"})", "baselineLayout: unknown value 'atlas' (faces, uv)"},
        {R"({"endCaps": "legacy"})", "endCaps: unknown value 'legacy' (gregory, bspline)"},
        {R"({"endCaps": true})", "endCaps"},
        {R"({"effects": {"shadows": true}})",
         "scene 'bad.json': effects: unknown effect 'shadows' (known: technique, normals, autoTolerance, lod, "
         "tessellation, wireframe, texelFormat, texelPath)"},
        {R"({"effects": {"texelFormat": "fp16"}})", "effects.texelFormat: unknown value 'fp16' (float, half)"},
        {R"({"effects": {"texelPath": "texture"}})", "effects.texelPath: unknown value 'texture' (buffer, image)"},
        {R"({"effects": {"normals": "fancy"}})",
         "scene 'bad.json': effects.normals: unknown value 'fancy' (approximate, accurate, auto)"},
        {R"({"effects": {"technique": "raymarch"}})", "effects.technique: unknown value 'raymarch' (base, displaced, baseline)"},
        {R"({"effects": {"lod": "tf"}})", "effects.lod: unknown value 'tf' (off, tessfactor, texelratio)"},
        {R"({"effects": {"autoTolerance": -1}})", "effects.autoTolerance: -1 is out of range"},
        {R"({"effects": {"wireframe": "yes"}})", "effects.wireframe: expected true or false"},
        {R"({"effects": {"tessellation": {"method": "screen"}}})",
         "effects.tessellation.method: unknown value 'screen' (uniform, distance, edge, area)"},
        {R"({"effects": {"tessellation": {"value": 0}}})", "effects.tessellation.value: 0 is out of range (must be > 0)"},
        {R"({"effects": {"tessellation": {"value": -3}}})", "effects.tessellation.value: -3 is out of range"},
        {R"({"effects": {"tessellation": {"max": 65}}})", "effects.tessellation.max: 65 is out of range (must be <= 64)"},
        {R"({"effects": {"tessellation": {"max": 0.5}}})", "effects.tessellation.max: 0.5 is out of range (must be >= 1)"},
        {R"({"effects": {"tessellation": {"spacing": "fractional_odd"}}})",
         "effects.tessellation.spacing: unknown value 'fractional_odd' (fractional_even, integer)"},
        {R"({"effects": {"tessellation": {"factor": 3}}})", "effects.tessellation: unknown key 'factor' (known: method,"},
    };
    for (const auto& [json, message] : rows) {
        INFO(json);
        CHECK_THROWS_MSG(parseScene(json, "bad.json", ""), SceneError, Catch::Contains(message));
    }
    // A SceneError is an ArgumentError, so callers that catch that (or dispmap::Error) see it.
    CHECK_THROWS_AS(parseScene("{\"isolation\": 0}", "x", ""), ArgumentError);
}

TEST_CASE("scene: files, relative paths, and tiles from each source", "[scene]") {
    TempDir dir;
    std::filesystem::create_directories(dir.path / "assets");
    writeText(dir.file("assets/grid.obj"), dmtest::gridObj(3, 2));
    HeightImage img;
    img.width = 8;
    img.height = 4;
    for (int i = 0; i < 32; ++i) img.values.push_back(float(i % 7) / 6.0f);
    writeHeightPng16(dir.file("assets/h.png"), img);

    SECTION("a missing scene file is a FileError naming it") {
        CHECK_THROWS_MSG(loadScene(dir.file("nope.json")), FileError, Catch::Contains("nope.json"));
    }
    SECTION("a height image, resolved against the scene's directory") {
        writeText(dir.file("s.json"), R"({"mesh": "assets/grid.obj",
            "displacement": {"height": "assets/h.png", "scale": 0.5, "offset": 0.1, "k": 3}})");
        const Scene s = loadScene(dir.file("s.json"));
        CHECK(s.name == dir.file("s.json"));
        CHECK(s.baseDir == dir.path.string());
        CHECK(resolveScenePath(s, "assets/h.png") == dir.file("assets/h.png"));
        CHECK(resolveScenePath(s, "/abs/x.png") == "/abs/x.png");
        const ControlMesh mesh = sceneMesh(s);
        CHECK(mesh.ptexFaceCount() == 6);
        const TileSet tiles = sceneTiles(s, mesh);
        CHECK(tiles.tileCount() == 6);
        // D = 0.1 + 0.5 h, h in [0, 1]; the interpolating fit overshoots a little at most.
        for (int f = 0; f < 6; ++f) {
            const double d = tiles.evaluate(f, 0, glm::dvec2(0.5, 0.5));
            CHECK(d > 0.0);
            CHECK(d < 0.7);
        }
        // The same scene from another working directory sees the same files: the scene's
        // own directory is the base, not the process's.
        const Scene t = parseScene(toJson(s), s.name, s.baseDir);
        CHECK(sceneTiles(t, sceneMesh(t)).tiles[3].coefficients == tiles.tiles[3].coefficients);
        // Missing files named.
        Scene m = s;
        m.displacement.height = "assets/missing.png";
        CHECK_THROWS_MSG(sceneTiles(m, mesh), FileError, Catch::Contains("missing.png"));
        m.mesh = "assets/missing.obj";
        CHECK_THROWS_MSG(sceneMesh(m), FileError, Catch::Contains("missing.obj"));
    }
    SECTION("a height image on a mesh without texture coordinates: a SceneError") {
        const Scene s = parseScene(R"({"displacement": {"height": "assets/h.png"}})", "s.json", dir.path.string());
        CHECK_THROWS_MSG(sceneTiles(s, sceneMesh(s)), SceneError,
                             Catch::Contains("scene 's.json': displacement:") &&
                                 Catch::Contains("no texture coordinates"));
    }
    SECTION("a tile file: loaded bit for bit, and refused for another mesh") {
        const ControlMesh box = builtin::defaultMesh();
        const TileSet saved = buildTiles(box, uniformTileSizes(box, 3), dmtest::roughSource);
        saveTiles(saved, dir.file("assets/box.dmt"));
        const Scene s = parseScene(R"({"displacement": {"tiles": "assets/box.dmt", "k": 6}})", "t.json",
                                   dir.path.string());
        const TileSet loaded = sceneTiles(s, box);
        REQUIRE(loaded.tileCount() == saved.tileCount());
        for (std::size_t t = 0; t < saved.tiles.size(); ++t)
            CHECK(loaded.tiles[t].coefficients == saved.tiles[t].coefficients);
        const Scene torus = parseScene(R"({"mesh": "builtin:torus", "displacement": {"tiles": "assets/box.dmt"}})",
                                       "t.json", dir.path.string());
        CHECK_THROWS_MSG(sceneTiles(torus, sceneMesh(torus)), SceneError,
                             Catch::Contains("displacement.tiles") &&
                                 Catch::Contains("was built for another mesh"));
    }
    SECTION("k too small for the box's sub-faces: a SceneError") {
        const Scene s = parseScene(R"({"displacement": {"k": 1}})", "k.json", "");
        CHECK_THROWS_MSG(sceneTiles(s, sceneMesh(s)), SceneError, Catch::Contains("k >= 2"));
    }
}

TEST_CASE("scene: zero displacement, filters, and mixed tile sizes", "[scene][mixed]") {
    {
        const Scene s = parseScene(R"({"displacement": {"function": "zero", "k": 2, "filter": "bwavelet"}})", "z", "");
        const ControlMesh mesh = sceneMesh(s);
        const TileSet tiles = sceneTiles(s, mesh);
        CHECK(tiles.filter == MipFilter::BWavelet);
        for (const Tile& t : tiles.tiles)
            for (float c : t.coefficients) CHECK(c == 0.0f);
    }
    {
        // The torus: quads only, sizes k, k - 1, k - 2 by Ptex face id.
        const Scene s = parseScene(R"({"mesh": "builtin:torus", "displacement": {"k": 4, "mixedSizes": true}})", "m", "");
        const ControlMesh mesh = sceneMesh(s);
        CHECK(mesh.ptexFaceCount() == 48);
        const TileSet tiles = sceneTiles(s, mesh);
        std::set<int> sizes;
        for (int t = 0; t < tiles.tileCount(); ++t) {
            CHECK(tiles.tiles[std::size_t(t)].k == 4 - t % 3);
            sizes.insert(tiles.tiles[std::size_t(t)].k);
        }
        CHECK(sizes == std::set<int>{2, 3, 4});
        // Clamped at kMinTileLog2.
        const std::vector<int> k2 = mixedTileSizes(mesh, 2);
        for (int t = 0; t < 48; ++t) CHECK(k2[std::size_t(t)] == std::max(1, 2 - t % 3));
        // The surface built on them is continuous (the builder's own tests check C1; here it
        // must only build and evaluate).
        const BaseSurface base(mesh);
        const DisplacedSurface ds(base, tiles);
        CHECK(std::isfinite(ds.evaluate<double>(5, 0.3, 0.7, NormalMode::Accurate).position.x));
    }
    {
        // Non-quads: quads at a T-junction keep k (the builder requires it); others mix.
        // A 5 x 5 grid whose corner quad is split into two triangles.
        std::string obj;
        for (int j = 0; j <= 5; ++j)
            for (int i = 0; i <= 5; ++i) obj += "v " + std::to_string(i) + " " + std::to_string(j) + " 0\n";
        const auto id = [](int i, int j) { return std::to_string(j * 6 + i + 1); };
        obj += "f " + id(0, 0) + " " + id(1, 0) + " " + id(1, 1) + "\nf " + id(0, 0) + " " + id(1, 1) + " " + id(0, 1) + "\n";
        for (int j = 0; j < 5; ++j)
            for (int i = 0; i < 5; ++i)
                if (i + j > 0) obj += "f " + id(i, j) + " " + id(i + 1, j) + " " + id(i + 1, j + 1) + " " + id(i, j + 1) + "\n";
        const ControlMesh nq = ControlMesh::fromObjText(obj, "split grid");
        const std::vector<int> u = uniformTileSizes(nq, 4), m = mixedTileSizes(nq, 4);
        int changed = 0;
        for (std::size_t t = 0; t < u.size(); ++t) changed += m[t] != u[t];
        CHECK(changed > 0);
        CHECK_NOTHROW(buildTiles(nq, m, dmtest::roughSource));
        const ControlMesh box = builtin::defaultMesh();
        CHECK_NOTHROW(buildTiles(box, mixedTileSizes(box, 5), builtin::defaultDisplacement));
    }
}

TEST_CASE("builtin: meshes by name", "[scene][builtin]") {
    CHECK(builtin::builtinMesh("box").ptexFaceCount() == 21);
    CHECK(builtin::builtinMesh("torus").ptexFaceCount() == 48);
    CHECK_THROWS_MSG(builtin::builtinMesh("teapot"), ArgumentError,
                         Catch::Contains("unknown built-in mesh 'teapot' (known: box, torus)"));
    CHECK_THROWS_AS(builtin::torusCage(2, 4, 2.0, 1.0, "bad"), ArgumentError);
    CHECK_THROWS_AS(builtin::torusCage(4, 4, 1.0, 1.0, "bad"), ArgumentError);
    CHECK(std::abs(builtin::defaultDisplacement(3, 0.2, 0.9)) <= 0.07);
    CHECK(builtin::torusDisplacement(4, 0.0, 0.5) == Approx(0.0).margin(1e-12)); // the far side: no amplitude
}

} // namespace dmtest_scene
