// dispmap: the command-line program.
//   dispmap demo                      build the embedded default tile set, print its figures
//   dispmap tiles --mesh M.obj ...    build (or --load) a tile set, print statistics, save it
//   dispmap eval --mesh M.obj --at f,u,v   the displaced surface at points, as JSON
//   dispmap tessellate --mesh M.obj -o out.ply   a watertight triangle mesh of the displaced surface
//   dispmap bench [gbench args]       the benchmark table and the timings
//   dispmap parity                    every kernel on the GPU (lavapipe by default) against C++
//   dispmap render [SCENE] -o out.png render a scene file (or the embedded default) headless
//   dispmap meso --height h.png -o m.dmm   mesostructure maps from a height image; --table: the table
//   dispmap maps --table / --seams    the displacement-map table; the traditional baseline at UV seams (Figure 7)
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <string_view>
#include <memory>
#include <optional>
#include <vector>

#include "dispmap/surface/displaced_surface.h"
#include "dispmap/core/parallel.h"
#include "dispmap/core/file_io.h"
#include "dispmap/io/image_files.h"
#include "dispmap/io/png.h"
#include "dispmap/io/meso_file.h"
#include "dispmap/scene/meso.h"
#include "dispmap/meso/solid.h"
#include "dispmap/scene/build.h"
#include "dispmap/scene/scene.h"
#include "dispmap/io/mesh_writers.h"
#include "dispmap/surface/tessellator.h"
#include "dispmap/surface/tile_builder.h"
#include "dispmap/surface/uv_map.h"
#include "dispmap/io/tile_file.h"
#include "dispmap/vulkan/context.h"
#include "figures.h"
#include "meso.h"
#include "swim.h"
#include "parity.h"
#include "render.h"
#include "bake.h"
#include "maps_table.h"
#include "uv_seams_table.h"
#include "cores_table.h"
#include "cages_table.h"
#include "embree_table.h"
#include "gltf_export.h"
#include "seams_table.h"

using namespace dispmap;

namespace {
int demo(bool quick) {
    ControlMesh mesh = figures::defaultMesh();
    BuildReport rep;
    TileSet ts = buildTiles(mesh, uniformTileSizes(mesh, 5), figures::defaultDisplacement, {}, &rep);
    figures::printTileStats(std::cout, "Default scene (embedded box with a pentagon and a triangle, k = 5):", ts, &rep);
    std::cout << "\n";
    figures::printMipTable(std::cout, "");
    std::cout << "\n";
    figures::printNormalTable(std::cout, "");
    std::cout << "\n";
    figures::printSwimFigure(std::cout, "");
    std::cout << "\n";
    figures::printRenderTable(std::cout, {"dispmap-demo", "", quick ? 2 : 3, 1, !quick, "", ""});
    std::cout << "(images in dispmap-demo/)\n\n";
    figures::MesoTableArgs meso;
    meso.dataDir = DISPMAP_EXAMPLE_DATA;
    meso.images = "dispmap-demo";
    meso.minSeconds = quick ? 0.02 : 0.15;
    figures::printMesoTable(std::cout, meso);
    std::cout << "\nTimings (Google Benchmark" << (quick ? ", short runs" : "") << "):\n" << std::flush;
    std::vector<std::string> flags;
    if (quick) flags.push_back("--benchmark_min_time=0.05");
    return figures::runBenchmarks(flags);
}

// The displacement of a control mesh, as `tiles`, `eval` and `tessellate` take it: a height
// image, a procedural function, or a saved tile file.
struct SourceArgs {
    std::string mesh, height, load, filter = "haar", function = "waves";
    std::string channel, uv = "mesh", mapFilter = "point", sizes = "uniform";
    int k = 4;
    double scale = 0.1, offset = 0.0, midLevel = 0.0, sizeTolerance = 0.02;
    bool wrap = false, allowOverlap = false;
};

void addSourceOptions(CLI::App* cmd, SourceArgs& a) {
    cmd->add_option("--mesh", a.mesh, "control mesh (OBJ, OpenSubdiv tags)");
    cmd->add_option("--height", a.height, "UV-mapped height image: PNG (8/16-bit grey), EXR (half/float), TIFF (8/16/32-bit); "
                                          "a UDIM set when the name holds <UDIM> (map.<UDIM>.exr)");
    cmd->add_option("--channel", a.channel, "the image's channel: EXR name (R, Y, ...), or TIFF sample 0, 1, ... (default: the only one)");
    cmd->add_option("--scale", a.scale, "displacement = offset + scale * (height - mid-level) (or the function's amplitude)");
    cmd->add_option("--offset", a.offset, "displacement offset");
    cmd->add_option("--mid-level", a.midLevel, "the height that means no displacement (sculpting tools: 0 or 0.5)");
    cmd->add_option("--uv", a.uv, "UV interpolation: mesh (the OBJ's facevaryinginterpolateboundary tag, else linear), linear, "
                                  "smooth, corners, corners+1, corners+2, boundaries");
    cmd->add_option("--map-filter", a.mapFilter, "each sample of the map: point, box (its footprint), tent (twice its footprint)");
    cmd->add_option("--sizes", a.sizes, "tile sizes: uniform (2^k), texels (per face from the map's texel density, at most 2^k), "
                                        "error (per face the smallest whose samples stay within --size-tolerance of 2^k's)");
    cmd->add_option("--size-tolerance", a.sizeTolerance, "with --sizes error: the error smaller tiles may add, in the map's "
                                                         "height units, (0, 1] (default 0.02)");
    cmd->add_flag("--allow-overlap", a.allowOverlap, "accept faces that overlap in UV space");
    cmd->add_flag("--wrap", a.wrap, "wrap texture coordinates outside [0, 1]");
    cmd->add_option("--function", a.function, "procedural source when no image: waves, zero");
    cmd->add_option("-k,--size", a.k, "log2 tile size of quads (sub-faces of non-quads get k - 1)");
    cmd->add_option("--filter", a.filter, "mip filter: haar, bwavelet");
    cmd->add_option("--load", a.load, "read a tile file instead (with --mesh: check it matches)");
}

// The displacement `a` describes, as a scene's; --scale and --offset checked (by the scene's
// rule: |offset| + |scale| <= kMaxDisplacement), named as options.
SceneDisplacement sceneDisplacement(const SourceArgs& a) {
    SceneDisplacement d;
    d.function = a.function;
    d.height = a.height;
    d.tiles = a.load;
    d.scale = a.scale;
    d.offset = a.offset;
    d.wrap = a.wrap;
    d.channel = a.channel;
    d.midLevel = a.midLevel;
    d.uv = a.uv;
    d.mapFilter = a.mapFilter;
    d.sizes = a.sizes;
    d.sizeTolerance = a.sizeTolerance;
    d.allowOverlap = a.allowOverlap;
    d.k = a.k;
    d.filter = a.filter;
    if (const std::optional<DrawProblem> p = displacementProblem(d)) throw ArgumentError("--scale / --offset: " + p->why);
    return d;
}

// Builds (or loads) the tile set of `mesh` that `a` describes (as a scene's displacement).
TileSet makeTiles(const ControlMesh& mesh, const SourceArgs& a, BuildReport* report) {
    return displacementTiles(mesh, sceneDisplacement(a), report);
}

ControlMesh loadMesh(const SourceArgs& a, const char* command) {
    if (a.mesh.empty()) throw ArgumentError(std::string(command) + ": give --mesh");
    (void)sceneDisplacement(a); // the options first: the mesh can take a while to read
    return ControlMesh::fromObjFile(a.mesh);
}

// The surface options `eval` and `tessellate` share.
struct SurfaceArgs {
    int isolation = 6;
    std::string endCaps = "gregory";
    double autoToleranceDeg = 2.0;
};

void addSurfaceOptions(CLI::App* cmd, SurfaceArgs& a) {
    cmd->add_option("--isolation", a.isolation, "OpenSubdiv adaptive isolation level (1..10)");
    cmd->add_option("--end-caps", a.endCaps, "OpenSubdiv end caps around extraordinary vertices: gregory or bspline (less memory)")
        ->check(CLI::IsMember({"gregory", "bspline"}));
    cmd->add_option("--auto-tolerance", a.autoToleranceDeg, "auto normals: accepted error in degrees");
}

BaseSurfaceOptions baseOptions(const SurfaceArgs& a) {
    BaseSurfaceOptions o;
    o.isolationLevel = a.isolation;
    o.gregoryEndCaps = a.endCaps == "gregory";
    return o;
}

DisplacedSurfaceOptions displacedOptions(const SurfaceArgs& a) {
    if (!std::isfinite(a.autoToleranceDeg) || a.autoToleranceDeg < 0)
        throw ArgumentError("--auto-tolerance must be a finite angle >= 0 (degrees)");
    DisplacedSurfaceOptions o;
    o.autoTolerance = a.autoToleranceDeg * 3.14159265358979323846 / 180.0;
    return o;
}

// Mesh, tiles and surfaces built once and kept together: the surfaces point at the others.
struct LoadedSurface {
    ControlMesh mesh;
    TileSet tiles;
    BaseSurface base;
    DisplacedSurface surface;
    LoadedSurface(const SourceArgs& source, const SurfaceArgs& a, const char* command)
        : mesh(loadMesh(source, command)), tiles(makeTiles(mesh, source, nullptr)), base(mesh, baseOptions(a)),
          surface(base, tiles, displacedOptions(a)) {}
};

// Writes the tiles back into the UV layout (tilesToMap): one image, or one per UDIM tile of
// the height map when `path` holds a UDIM token; the format by the extension (.exr float,
// .tif 32-bit float, .png 16-bit: heights in [0, 1]); size: `size`, or the height map's.
// Whether `path` ends in `ext` (and has a name before it).
bool endsWith(const std::string& path, std::string_view ext) {
    return path.size() > ext.size() && path.compare(path.size() - ext.size(), ext.size(), ext) == 0;
}

// tiles() checked the extension and that `path` is a UDIM pattern exactly when --height is.
void writeMaps(const ControlMesh& mesh, const TileSet& ts, const SourceArgs& a, const std::string& path, int size) {
    const std::optional<UvInterpolation> rule = parseUvInterpolation(a.uv);
    if (!rule) throw ArgumentError("--uv: unknown rule '" + a.uv + "' (" + uvInterpolationNames() + ")");
    const UvMap uvs(mesh, *rule);
    HeightMaps maps;
    if (!a.height.empty()) {
        HeightReadOptions ro;
        ro.channel = a.channel;
        maps = readHeightMaps(a.height, ro);
    }
    const bool udim = maps.udim;
    std::vector<int> tilesToWrite;
    if (udim)
        for (const auto& [n, img] : maps.images) tilesToWrite.push_back(n);
    else
        tilesToWrite.push_back(0);
    for (int tile : tilesToWrite) {
        const auto it = maps.images.find(tile);
        const int w = size > 0 ? size : it != maps.images.end() ? it->second->width : 1024;
        const int h = size > 0 ? size : it != maps.images.end() ? it->second->height : 1024;
        const HeightImage img = tilesToMap(uvs, ts, tile, w, h, a.scale, a.offset, a.midLevel, nullptr, a.wrap && !udim);
        const std::string file = udim ? udimPath(path, tile) : path;
        if (endsWith(file, ".exr"))
            writeHeightExr(file, img);
        else if (endsWith(file, ".tif") || endsWith(file, ".tiff"))
            writeHeightTiff(file, img, 32, true);
        else
            writeHeightPng16(file, img);
        std::cout << "  wrote " << file << " (" << w << " x " << h << ")\n";
    }
}

int tiles(const SourceArgs& a, const std::string& output, const std::string& mapOutput, int mapSize) {
    if (!a.load.empty() && a.mesh.empty()) {
        if (!mapOutput.empty()) throw ArgumentError("--write-map needs --mesh (the UV layout)");
        TileSet ts = loadTiles(a.load);
        figures::printTileStats(std::cout, "Tile file " + a.load + ":", ts, nullptr);
        return 0;
    }
    if (a.mesh.empty()) throw ArgumentError("tiles: give --mesh (with --height or --function) or --load");
    if (!output.empty()) detail::checkOutputPath(output, "tile file");
    if (!mapOutput.empty()) {
        if (!endsWith(mapOutput, ".exr") && !endsWith(mapOutput, ".tif") && !endsWith(mapOutput, ".tiff") &&
            !endsWith(mapOutput, ".png"))
            throw ArgumentError("--write-map: '" + mapOutput + "' must end in .exr, .tif or .png");
        if (isUdimPattern(mapOutput) != (!a.height.empty() && isUdimPattern(a.height)))
            throw ArgumentError(std::string("--write-map: ") + (isUdimPattern(mapOutput) ? "a UDIM pattern needs a UDIM --height set"
                                                                                            : "the --height set is UDIM: give a pattern with <UDIM>"));
        if (mapSize < 0 || mapSize > kMaxHeightImageSize)
            throw ArgumentError("--map-size " + std::to_string(mapSize) + " out of range [0 (the height map's size), " +
                                std::to_string(kMaxHeightImageSize) + "]");
        if (!isUdimPattern(mapOutput)) detail::checkOutputPath(mapOutput, "map image");
    }
    ControlMesh mesh = loadMesh(a, "tiles");
    BuildReport rep;
    TileSet ts = makeTiles(mesh, a, &rep);
    figures::printTileStats(std::cout, (a.load.empty() ? "Tiles of " + a.mesh : "Tile file " + a.load) + ":", ts,
                            a.load.empty() ? &rep : nullptr);
    if (!output.empty()) {
        saveTiles(ts, output);
        std::cout << "  saved " << output << "\n";
    }
    if (!mapOutput.empty()) writeMaps(mesh, ts, a, mapOutput, mapSize);
    return 0;
}

struct EvalArgs {
    SourceArgs source;
    SurfaceArgs surface;
    std::vector<std::string> at;
    int grid = 0;
    double rho = kFinest;
    bool single = false;
    std::string output;
};

// Three comma-separated numbers ("3,0.25,0.5" or "0,0,4"); `what` names the option and the
// expected form in the error.
glm::dvec3 parseTriple(const std::string& text, const std::string& what) {
    std::istringstream in(text);
    glm::dvec3 p;
    char c1 = 0, c2 = 0;
    if (!(in >> p.x >> c1 >> p.y >> c2 >> p.z) || c1 != ',' || c2 != ',' || !(in >> std::ws).eof())
        throw ArgumentError(what.substr(0, what.find(' ')) + " '" + text + "': expected " + what.substr(what.find(' ') + 1));
    return p;
}

nlohmann::json vec(glm::dvec3 a) {
    for (int i = 0; i < 3; ++i)
        if (!std::isfinite(a[i])) throw Error("a non-finite value reached the output (a bug: please report)");
    return nlohmann::json::array({a.x, a.y, a.z});
}

template <typename real> nlohmann::json evalPoint(const DisplacedSurface& ds, int f, double u, double v, double rho) {
    const real ru = static_cast<real>(u), rv = static_cast<real>(v), rr = static_cast<real>(rho);
    const BaseSample<real> b = ds.base().evaluate<real>(f, ru, rv, true);
    const SurfaceSample<real> ap = ds.evaluate<real>(f, ru, rv, NormalMode::Approximate, rr);
    const SurfaceSample<real> ac = ds.evaluate<real>(f, ru, rv, NormalMode::Accurate, rr);
    const SurfaceSample<real> au = ds.evaluate<real>(f, ru, rv, NormalMode::Auto, rr);
    nlohmann::json j;
    j["face"] = f;
    j["u"] = u;
    j["v"] = v;
    j["position"] = vec(ac.position);
    j["displacement"] = {{"D", static_cast<double>(ac.displacement.x)},
                         {"D_u", static_cast<double>(ac.displacement.y)},
                         {"D_v", static_cast<double>(ac.displacement.z)}};
    j["base"] = {{"position", vec(b.p)},   {"du", vec(b.du)},   {"dv", vec(b.dv)},
                 {"duu", vec(b.duu)},      {"duv", vec(b.duv)}, {"dvv", vec(b.dvv)},
                 {"normal", vec(ac.baseNormal)}, {"limitNormalWeight", static_cast<double>(b.evWeight)}};
    j["normal"] = {{"approximate", vec(ap.normal)}, {"accurate", vec(ac.normal)}, {"auto", vec(au.normal)}};
    j["du"] = {{"approximate", vec(ap.du)}, {"accurate", vec(ac.du)}};
    j["dv"] = {{"approximate", vec(ap.dv)}, {"accurate", vec(ac.dv)}};
    j["autoAccurate"] = au.accurate;
    return j;
}

int eval(const EvalArgs& a) {
    if (std::isnan(a.rho)) throw ArgumentError("eval: --rho must be a number");
    if (a.grid < 0 || a.grid > 1024) throw ArgumentError("eval: --grid must be in [0, 1024]");
    if (a.at.empty() && a.grid == 0) throw ArgumentError("eval: give points with --at face,u,v or --grid N");
    if (!a.output.empty()) detail::checkOutputPath(a.output, "JSON output");
    const LoadedSurface loaded(a.source, a.surface, "eval");
    const BaseSurface& base = loaded.base;
    const DisplacedSurface& ds = loaded.surface;
    nlohmann::json out;
    out["mesh"] = a.source.mesh;
    out["ptexFaces"] = base.faceCount();
    out["isolationLevel"] = a.surface.isolation;
    out["endCaps"] = a.surface.endCaps;
    out["precision"] = a.single ? "float" : "double";
    out["autoToleranceDegrees"] = a.surface.autoToleranceDeg;
    out["autoAccurateFaces"] = ds.autoAccurateCount();
    nlohmann::json points = nlohmann::json::array();
    auto one = [&](int f, double u, double v) {
        points.push_back(a.single ? evalPoint<float>(ds, f, u, v, a.rho) : evalPoint<double>(ds, f, u, v, a.rho));
    };
    for (const std::string& p : a.at) {
        const glm::dvec3 x = parseTriple(p, "--at face,u,v (e.g. 3,0.25,0.5)");
        if (x.x != std::floor(x.x) || std::abs(x.x) > 1e9) throw ArgumentError("--at '" + p + "': the face id must be an integer");
        one(static_cast<int>(x.x), x.y, x.z);
    }
    if (a.grid > 0)
        for (int f = 0; f < base.faceCount(); ++f) {
            if (base.isHole(f)) continue;
            for (int j = 0; j < a.grid; ++j)
                for (int i = 0; i < a.grid; ++i) one(f, (i + 0.5) / a.grid, (j + 0.5) / a.grid);
        }
    out["points"] = std::move(points);
    const std::string text = out.dump(2) + "\n";
    if (a.output.empty()) {
        std::cout << text;
    } else {
        detail::writeFileAtomically(a.output, std::vector<unsigned char>(text.begin(), text.end()), "JSON output");
        std::cout << "wrote " << out["points"].size() << " points to " << a.output << "\n";
    }
    return 0;
}

struct TessellateArgs {
    SourceArgs source;
    SurfaceArgs surface;
    TessellateOptions options;
    std::string output, eye;
    double factor = 8, distance = 0;
};

int tessellateCommand(const TessellateArgs& a) {
    if (a.output.empty()) throw ArgumentError("tessellate: give -o out.obj, out.ply, out.glb or out.gltf");
    const bool ply = endsWith(a.output, ".ply"), obj = endsWith(a.output, ".obj"),
               gltf = endsWith(a.output, ".glb") || endsWith(a.output, ".gltf");
    if (!ply && !obj && !gltf) throw ArgumentError("tessellate: -o must name a .obj, a .ply, a .glb or a .gltf file");
    detail::checkOutputPath(a.output, "mesh file");
    const LoadedSurface loaded(a.source, a.surface, "tessellate");
    const BaseSurface& base = loaded.base;
    const TessFactors factors = a.eye.empty() ? uniformTessFactors(base, a.factor)
                                              : distanceTessFactors(base, parseTriple(a.eye, "--eye x,y,z"), a.distance);
    // The output grows with the square of the factors: refused before anything is made.
    const Tessellator tessellator(loaded.surface, factors, a.options);
    if (const TessellationSize size = tessellator.estimate(); size.bytes > a.options.maxBytes)
        throw ArgumentError("tessellate: " + std::to_string(size.triangles) + " triangles would take about " +
                            std::to_string(size.bytes >> 20) + " MiB, more than the " + std::to_string(a.options.maxBytes >> 20) +
                            " MiB a tessellation may take: lower " + (a.eye.empty() ? "--factor" : "--c") + " or --max-factor");
    const auto t0 = std::chrono::steady_clock::now();
    const TriangleMesh tessellated = tessellator.tessellate();
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    // Texture coordinates in the mesh's UV layout (by the --uv rule), where it has one; vertices
    // on UV seams are split, one copy per chart.
    TexturedMesh textured;
    if (loaded.mesh.hasUVs()) {
        const std::optional<UvInterpolation> rule = parseUvInterpolation(a.source.uv);
        if (!rule) throw ArgumentError("--uv: unknown rule '" + a.source.uv + "' (" + uvInterpolationNames() + ")");
        textured = texturedMesh(tessellated, UvMap(loaded.mesh, *rule));
    } else {
        textured.mesh = tessellated;
    }
    const TriangleMesh& m = textured.mesh;
    const std::vector<glm::dvec2>* tc = textured.texcoords.empty() ? nullptr : &textured.texcoords;
    if (ply) {
        MeshWriteOptions o;
        o.faceUV = true; // each vertex's Ptex (face, u, v): ptex_face, ptex_u, ptex_v
        o.texcoords = tc;
        writePly(m, a.output, o);
    } else if (gltf) {
        writeGltf(m, a.output, tc);
    } else {
        MeshWriteOptions o;
        o.texcoords = tc;
        writeObj(m, a.output, o);
    }
    std::cout << "tessellated " << base.faceCount() << " faces into " << m.triangleCount() << " triangles, "
              << m.vertexCount() << " vertices in " << ms << " ms (normals " << toString(a.options.normals) << ", spacing "
              << toString(a.options.spacing) << ", mips " << toString(a.options.mips) << "); wrote " << a.output << "\n";
    return 0;
}

struct ParityArgs {
    parity::Options options;
    std::string device;
    bool validation = false;
    bool strict = false, loose = false;
};

// Exit status 1 when a kernel is over its bound or the validation layer spoke.
int runParity(const ParityArgs& a) {
    vulkan::DeviceOptions dev;
    dev.device = a.device;
    dev.validation = a.validation;
    dev.float64 = vulkan::Float64::IfSupported; // without it only the float kernels run
    auto ctx = std::make_unique<vulkan::Context>(dev);
    parity::Options opt = a.options;
    if (a.strict) opt.strict = 1;
    if (a.loose) opt.strict = 0;
    auto results = parity::run(*ctx, opt);
    parity::printTable(std::cout, results, ctx->deviceName(), parity::strictFor(*ctx, opt));
    int status = 0;
    for (const auto& r : results) status |= r.ok() ? 0 : 1;
    for (const std::string& m : ctx->takeValidationMessages()) {
        std::cerr << "validation: " << m << "\n";
        status = 1;
    }
    return status;
}
struct MesoArgs {
    std::string height, mesh, output, cones = "4x1", csv, images, data = DISPMAP_EXAMPLE_DATA;
    int layers = 16, block = 4, size = 0, gpuWarmup = 1;
    double depth = -1;
    float spread = kDefaultCompressionSpread;
    bool shadow = false, table = false, curved = false;
};

int mesoCommand(const MesoArgs& a) {
    if (a.gpuWarmup < 0 || a.gpuWarmup > figures::kMaxRenderFrames)
        throw ArgumentError("--gpu-warmup " + std::to_string(a.gpuWarmup) + " is not in 0.." + std::to_string(figures::kMaxRenderFrames));
    if (a.table) {
        figures::MesoTableArgs t;
        t.dataDir = a.data;
        t.csv = a.csv;
        t.images = a.images;
        t.gpuWarmup = a.gpuWarmup;
        figures::printMesoTable(std::cout, t);
        return 0;
    }
    if (a.curved) {
        figures::MesoTableArgs t;
        t.dataDir = a.data;
        t.gpuWarmup = a.gpuWarmup;
        figures::printMesoCurvedTable(std::cout, t);
        return 0;
    }
    // Every option is checked before anything is read or built: the maps take seconds to
    // minutes, and a constraint the builders check last (the block size) must not cost them.
    if (!a.mesh.empty() && !a.height.empty()) throw ArgumentError("dispmap meso: give --height IMAGE or --mesh OBJ, not both");
    if (a.mesh.empty() && a.height.empty()) throw ArgumentError("dispmap meso: give --height IMAGE or --mesh OBJ (or --table)");
    if (a.size != 0 && (a.size < 2 || a.size > kMaxMesoSize))
        throw ArgumentError("dispmap meso: --size " + std::to_string(a.size) + " is out of range (2 .. " + std::to_string(kMaxMesoSize) +
                            (a.height.empty() ? ")" : "; leave it out for the image's own size)"));
    if (a.layers < 2 || a.layers > kMaxMesoLayers)
        throw ArgumentError("dispmap meso: --layers: " + std::to_string(a.layers) + " layers is out of range (2 .. " +
                            std::to_string(kMaxMesoLayers) + ")");
    if (a.depth != -1 && !(a.depth > 0 && a.depth <= a.layers))
        throw ArgumentError("dispmap meso: --depth " + std::to_string(a.depth) + " is not in (0, --layers = " + std::to_string(a.layers) + "]");
    if (!a.mesh.empty() && a.depth != -1) throw ArgumentError("dispmap meso: --depth applies to --height, not to --mesh");
    if (a.block < 1 || a.block > 32) throw ArgumentError("dispmap meso: --block " + std::to_string(a.block) + " is not in 1..32");
    if (!(a.spread >= 0.0f)) throw ArgumentError("dispmap meso: --spread " + std::to_string(a.spread) + " is not >= 0 (inf: the paper's rule)");
    if (!a.output.empty()) detail::checkOutputPath(a.output, "mesostructure file");
    MesoMapOptions o;
    o.cones = parseConeSet(a.cones, a.shadow);
    o.block = a.block;
    o.compressionSpread = a.spread;
    const auto check = [&](int width, int height) {
        if (const std::string why = mesoBuildProblem(width, height, a.layers, o); !why.empty())
            throw ArgumentError("dispmap meso: " + why + " (--size, --layers, --block, --cones)");
    };
    if (!a.mesh.empty()) {
        if (!a.output.empty()) throw ArgumentError("dispmap meso: the mesostructure file holds height-field maps; no -o with --mesh");
        const int size = a.size > 0 ? a.size : 32;
        const int sub = 2; // mesoSolidFromMesh's sub-voxels per axis
        const TriangleSoup soup = readObjTriangles(a.mesh);
        {
            // mesoSolidFromMesh's first refusal (x and y scaled onto the tile, z alike), here so
            // that it comes before the checks below as it did: the voxelisation after them is
            // the slow part.
            glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
            for (const glm::dvec3& v : soup.positions) {
                lo = glm::min(lo, v);
                hi = glm::max(hi, v);
            }
            const glm::dvec3 ext = hi - lo;
            const double tall = ext.z * std::min(size / ext.x, size / ext.y);
            if (ext.x > 0 && ext.y > 0 && std::isfinite(tall) && tall > a.layers)
                throw ArgumentError("dispmap meso: the mesh is " + std::to_string(tall) + " voxels tall, more than " +
                                    std::to_string(a.layers) + " layers (--layers, --size)");
        }
        check(size, size);
        if (const std::uint64_t bytes = mesoSolidBuildBytes(size, size, a.layers, sub, o.cones); bytes > kMaxMesoBuildBytes)
            throw ArgumentError("dispmap meso: a mesh voxelised into " + std::to_string(size) + " x " + std::to_string(size) + " x " +
                                std::to_string(a.layers) + " voxels would take about " + std::to_string(bytes >> 20) +
                                " MiB while its maps are built, more than " + std::to_string(kMaxMesoBuildBytes >> 20) +
                                " MiB: lower --size or --layers");
        const auto t0 = std::chrono::steady_clock::now();
        const MesoSolid solid = mesoSolidFromMesh(soup.positions, soup.triangles, size, size, a.layers, sub);
        const DistanceMap dm = buildSolidDistanceMap(solid);
        const DirectionalDistanceMap ddm = buildSolidDdm(solid, o.cones);
        const CompressedDdm c = compressDdm(ddm, a.block, a.spread);
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::cout << "mesh mesostructure " << solid.triangles.size() << " triangles -> " << size << " x " << size << " x " << a.layers
                  << " voxels (" << 100 * solid.solidShare() << " % solid), cones " << o.cones.name() << ": distance map "
                  << dm.bytes() / 1024 << " KiB, DDM " << ddm.bytes() / 1024 << " KiB -> grid " << c.grid.size() * 4 / 1024
                  << " KiB + atlas " << c.atlas.size() * 4 / 1024 << " KiB (ratio " << c.ratio() << "), built in " << s << " s\n";
        return 0;
    }
    if (a.size > 0) check(a.size, a.size);
    // Without --size the image is the field: at most kMaxMesoSize per side, refused from its
    // header before it is decoded.
    HeightImage img = readHeightPng(a.height, a.size > 0 ? kMaxHeightImageSize : kMaxMesoSize,
                                    " for a mesostructure (give --size to box-filter it smaller)");
    if (a.size > 0) img = downsampleHeightImage(img, a.size);
    check(img.width, img.height);
    const MesoHeightField hf = mesoHeightFieldFromImage(img, a.layers, a.depth);
    const auto t0 = std::chrono::steady_clock::now();
    const MesoMaps m = buildMesoMaps(hf, o);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "mesostructure " << hf.width << " x " << hf.height << " x " << hf.layers << " voxels, cones " << o.cones.name()
              << ": distance map " << m.distance.bytes() / 1024 << " KiB, DDM " << m.denseDdmBytes / 1024 << " KiB -> grid "
              << m.ddm.grid.size() * 4 / 1024 << " KiB + atlas " << m.ddm.atlas.size() * 4 / 1024 << " KiB (ratio "
              << m.ddm.ratio() << "), quadrics " << m.quadrics.bytes() / 1024 << " KiB, built in " << s << " s\n";
    if (!a.output.empty()) {
        saveMesoMaps(m, a.output);
        std::cout << "wrote " << a.output << "\n";
    }
    return 0;
}
} // namespace

int main(int argc, char** argv) {
    CLI::App app{"dispmap: analytic displacement mapping on Catmull-Clark surfaces"};
    app.require_subcommand(1);
    // One thread count for every parallel stage of every command (the library's entry points
    // take theirs in their options; 0 there means what this allows).
    int threads = 0;
    const char* threadsHelp = "threads of every parallel stage (0: all cores; 1: one, the calling thread)";
    app.add_option("--threads", threads, threadsHelp);
    bool quick = false;
    auto* demoCmd = app.add_subcommand("demo", "build the embedded default tile set and print its figures");
    demoCmd->add_flag("--quick", quick, "short benchmark runs");
    SourceArgs ta;
    std::string tilesOutput;
    auto* tilesCmd = app.add_subcommand("tiles", "build a tile set from a mesh and a displacement source");
    addSourceOptions(tilesCmd, ta);
    tilesCmd->add_option("-o,--output", tilesOutput, "write the tile file");
    std::string mapOutput;
    int mapSize = 0;
    tilesCmd->add_option("--write-map", mapOutput, "write the tiles back into the UV layout: out.exr, .tif or .png "
                                                   "(a UDIM pattern for a UDIM set)");
    tilesCmd->add_option("--map-size", mapSize, "width and height of --write-map (default: the height map's)");
    EvalArgs ea;
    auto* evalCmd = app.add_subcommand("eval", "evaluate the displaced surface at (face, u, v): JSON with positions, "
                                                "derivatives and the normal in each mode");
    addSourceOptions(evalCmd, ea.source);
    evalCmd->add_option("--at", ea.at, "a point: face,u,v (Ptex face id; repeat for more)");
    evalCmd->add_option("--grid", ea.grid, "also N x N cell centres on every face");
    addSurfaceOptions(evalCmd, ea.surface);
    evalCmd->add_option("--rho", ea.rho, "mip resolution to read (log2 of the level size; default: finest)");
    evalCmd->add_flag("--float", ea.single, "evaluate in single precision (default: double)");
    evalCmd->add_option("-o,--output", ea.output, "write the JSON here instead of standard output");
    TessellateArgs ts;
    auto* tessCmd = app.add_subcommand("tessellate", "tessellate the displaced surface into a watertight triangle mesh "
                                                      "(OBJ, PLY or glTF)");
    addSourceOptions(tessCmd, ts.source);
    tessCmd->add_option("-o,--output", ts.output,
                        "out.obj, out.ply (binary, with each vertex's Ptex face, u, v) or glTF 2.0 out.glb / out.gltf");
    tessCmd->add_option("--factor", ts.factor, "uniform tessellation factor (segments per base edge)");
    tessCmd->add_option("--eye", ts.eye, "x,y,z: distance-based factors c / |eye - vertex| instead (with --c)");
    tessCmd->add_option("--c", ts.distance, "constant of the distance-based factors");
    tessCmd->add_option("--max-factor", ts.options.maxFactor, "clamp of the factors (default 64, the hardware limit)");
    addSurfaceOptions(tessCmd, ts.surface);
    tessCmd->add_option("--normals", ts.options.normals, "approximate, accurate or auto")
        ->transform(CLI::CheckedTransformer(std::map<std::string, NormalMode>{{"approximate", NormalMode::Approximate},
                                                                              {"accurate", NormalMode::Accurate},
                                                                              {"auto", NormalMode::Auto}}));
    tessCmd->add_option("--spacing", ts.options.spacing, "fractional (continuous, like fractional_even) or integer")
        ->transform(CLI::CheckedTransformer(
            std::map<std::string, Spacing>{{"fractional", Spacing::FractionalEven}, {"integer", Spacing::Integer}}));
    tessCmd->add_option("--mips", ts.options.mips,
                        "mip selection from the factor: off, tf (log2 TF, paper 6.2), texelratio (seed004: its former name)")
        ->transform(CLI::CheckedTransformer(std::map<std::string, MipSelection>{{"off", MipSelection::Off},
                                                                                {"tf", MipSelection::TessFactor},
                                                                                {"texelratio", MipSelection::TexelRatio},
                                                                                {"seed004", MipSelection::TexelRatio}}));
    auto* benchCmd = app.add_subcommand("bench", "mip accuracy table and timings (Google Benchmark flags pass through)");
    std::string csv;
    benchCmd->add_option("--csv", csv, "also write the mip table as CSV");
    std::string normalsCsv, isolationCsv, swimCsv, tessCsv, editCsv, seamsCsv;
    benchCmd->add_option("--tessellation-csv", tessCsv, "also write the tessellation-factor table as CSV");
    benchCmd->add_option("--edit-csv", editCsv, "also write the edit (re-fit) table as CSV");
    benchCmd->add_option("--seams-csv", seamsCsv, "also write the seams table as CSV");
    std::string only;
    benchCmd->add_option("--only", only, "print only this table, no timings (embree and cages run only when named here)")
        ->check(CLI::IsMember({"mips", "normals", "isolation", "swim", "tessellation", "edit", "seams", "render", "cores", "embree", "cages"}));
    figures::CoresTableArgs cta;
    cta.dataDir = DISPMAP_EXAMPLE_DATA;
    benchCmd->add_flag("--quick", cta.quick, "with --only cores, embree or cages: the small version (CI)");
    benchCmd->add_option("--cores-csv", cta.csv, "also write the all-cores table as CSV");
    figures::EmbreeTableArgs eta;
    eta.dataDir = DISPMAP_EXAMPLE_DATA;
    eta.denseDir = DISPMAP_DENSE_DIR;
    benchCmd->add_option("--embree-csv", eta.csv, "also write the Embree side-by-side table as CSV");
    figures::CagesTableArgs gta;
    gta.denseDir = DISPMAP_DENSE_DIR;
    gta.dataDir = DISPMAP_EXAMPLE_DATA;
    benchCmd->add_option("--cages-csv", gta.csv, "also write the production-size cages table as CSV");
    benchCmd->add_option("--swim-csv", swimCsv, "also write the swimming figure as CSV");
    benchCmd->add_option("--isolation-csv", isolationCsv, "also write the isolation-level table as CSV");
    benchCmd->add_option("--normals-csv", normalsCsv, "also write the normals table as CSV");
    benchCmd->allow_extras();
    ParityArgs pa;
    auto* parityCmd = app.add_subcommand("parity", "run every kernel in a compute shader and in C++, compare");
    parityCmd->add_option("--inputs", pa.options.inputs, "inputs per kernel (exhaustive sets may add more)");
    parityCmd->add_option("--seed", pa.options.seed, "random seed of the input sets");
    parityCmd->add_option("--kernel", pa.options.filter, "only kernels whose name contains this");
    parityCmd->add_option("--device", pa.device, "Vulkan device: index or name substring (default: lavapipe)");
    parityCmd->add_flag("--validation", pa.validation, "enable the validation layer; any message fails");
    parityCmd->add_flag("--strict", pa.strict, "hold exact kernels to 0 ULP whatever the device");
    parityCmd->add_flag("--fused", pa.loose, "allow FMA contraction on exact kernels whatever the device");
    figures::RenderArgs ra;
    auto* renderCmd = app.add_subcommand("render", "render a scene (JSON; none: the embedded default) headless with "
                                                    "hardware tessellation, print GPU time, patches, triangles");
    renderCmd->add_option("scene", ra.scene, "scene file (JSON)");
    renderCmd->add_option("-o,--output", ra.output, "write the image (PNG)");
    renderCmd->add_option("--frames", ra.frames, "timed frames, 1..1000");
    renderCmd->add_option("--warmup", ra.warmup, "untimed frames before them, 0..1000 (default 1; a GPU raises its clocks under load: "
                                                 "docs/figures.md used 30 on an NVIDIA H200)");
    renderCmd->add_option("--faces-per-draw", ra.facesPerDraw,
                          "patches per draw call, 1..32 (lavapipe slows down sharply on bigger draws; default 16)");
    renderCmd->add_option("--device", ra.device, "Vulkan device: index or name substring (default: lavapipe)");
    renderCmd->add_flag("--validation", ra.validation, "enable the validation layer; any message fails");
    std::string renderCsv, renderImages;
    int renderFrames = 9;
    benchCmd->add_option("--render-csv", renderCsv, "also write the renderer table as CSV");
    benchCmd->add_option("--render-images", renderImages, "write the renderer table's images (PNG) to this folder");
    benchCmd->add_option("--render-frames", renderFrames, "timed frames per renderer row");
    int renderWarmup = 1;
    benchCmd->add_option("--render-warmup", renderWarmup,
                         "untimed frames before each renderer row's timed ones, 0..1000 (default 1; a GPU raises its clocks under load)");
    std::string renderScene;
    benchCmd->add_option("--render-scene", renderScene,
                         "the renderer table on this scene file (a surface scene: its mesh, displacement, camera, resolution) "
                         "instead of the default scene");
    MesoArgs ma;
    auto* mesoCmd = app.add_subcommand("meso", "per-pixel mesostructure: build the maps of a height image, or print the "
                                                "accuracy-vs-time table (--table)");
    mesoCmd->add_option("--height", ma.height, "height image (greyscale PNG, 8 or 16 bit), tiling");
    mesoCmd->add_option("--mesh", ma.mesh, "a closed triangle mesh (OBJ) for non-height-field detail, voxelised into --size^2 x --layers");
    mesoCmd->add_option("--layers", ma.layers, "voxel layers of the slab (2..256)");
    mesoCmd->add_option("--depth", ma.depth, "height of white in voxels (default: the layers)");
    mesoCmd->add_option("--cones", ma.cones, "direction cones MxN (M in 1,2,4,8; N in 1,2) or isotropic");
    mesoCmd->add_flag("--shadow", ma.shadow, "also the shadow cones (upward)");
    mesoCmd->add_option("--block", ma.block, "compression block size");
    mesoCmd->add_option("--spread", ma.spread,
                        "compression: free-space blocks whose distances spread by more voxels are stored whole (inf: the paper's "
                        "rule; --table prints every spread)");
    mesoCmd->add_option("--size", ma.size, "box-filter the image to SIZE x SIZE texels first");
    mesoCmd->add_option("-o,--output", ma.output, "write the maps (mesostructure file)");
    mesoCmd->add_flag("--table", ma.table, "the table: every method on the built-in scenes, iterations, error, memory, time");
    mesoCmd->add_flag("--curved", ma.curved, "the curved-base table: the locally planar march against an exact curved shell, and "
                                              "the renderer on Spot beside the plane");
    mesoCmd->add_option("--csv", ma.csv, "with --table: also write it as CSV");
    mesoCmd->add_option("--images", ma.images, "with --table: write the iteration pictures (PNG) to this folder");
    mesoCmd->add_option("--data", ma.data, "folder of the built-in scenes' images");
    mesoCmd->add_option("--gpu-warmup", ma.gpuWarmup, "with --table or --curved: untimed frames before each GPU row's timed ones, "
                                                      "0..1000 (default 1; a GPU raises its clocks under load)");
    figures::MapsTableArgs mta;
    mta.dataDir = DISPMAP_EXAMPLE_DATA;
    bool mapsTable = false;
    auto* mapsCmd = app.add_subcommand("maps", "displacement maps: print the table of formats, prefilters, tile sizes from the "
                                                "texel density and UV rules (docs/figures.md)");
    mapsCmd->add_flag("--table", mapsTable, "print the table (markdown)");
    mapsCmd->add_flag("--quick", mta.quick, "a 512 map for the formats rows instead of 2048, one frame a GPU row");
    mapsCmd->add_option("--device", mta.device, "Vulkan device of the GPU rows (name substring; default: the first)");
    bool mapsSeams = false;
    std::string mapsImages;
    mapsCmd->add_flag("--seams", mapsSeams, "print the Figure 7 table: the traditional baseline on the mesh's UVs at UV seams");
    mapsCmd->add_option("--images", mapsImages, "with --seams: write the pictures (PNG) to this folder");
    figures::BakeArgs ba;
    ba.denseDir = DISPMAP_DENSE_DIR;
    ba.skeletonDir = DISPMAP_SKELETON_DIR;
    ba.dataDir = DISPMAP_EXAMPLE_DATA;
    auto* bakeCmd = app.add_subcommand("bake", "bake a dense mesh (OBJ, PLY, OFF) into a base mesh (OBJ) and a tile file, with a "
                                                "JSON report; or print the accuracy-vs-time table (--table)");
    bakeCmd->add_option("input", ba.input, "the dense mesh (a scan or sculpt)");
    bakeCmd->add_option("--skeleton", ba.skeleton, "skeleton route: joints and segments (JSON, docs/bake.md)");
    bakeCmd->add_option("--base-faces", ba.baseFaces, "simplification route: decimate to N triangles first");
    bakeCmd->add_option("--density", ba.density, "samples per base face edge (the tiles' size): 2, 4, 8, 16, ...");
    bakeCmd->add_option("-o,--output", ba.output, "write the base mesh (OBJ)");
    bakeCmd->add_option("--tiles", ba.tiles, "write the tiles here (default: the base mesh's name with .dmt)");
    bakeCmd->add_option("--report", ba.report, "write the JSON report (errors, compression, seconds per stage, fitting)");
    bakeCmd->add_option("--heatmap", ba.heatmap, "write the result as PLY coloured by its distance to the dense mesh (0..1 %)");
    bakeCmd->add_option("--scene", ba.scene, "write a scene file that renders the result (dispmap render)");
    bakeCmd->add_option("--threads", ba.threads, "threads (0: all cores)");
    bakeCmd->add_option("--iterations", ba.iterations, "progressive fitting iterations at most");
    bakeCmd->add_option("--fit-samples", ba.fitSamples, "fitting samples per base face edge");
    bakeCmd->add_option("--shell", ba.shell, "the rays' reach, a fraction of the bounding-box diagonal");
    bakeCmd->add_option("--normal-weight", ba.normalWeight, "weight of the normal in the fitting's nearest-point metric");
    bakeCmd->add_flag("--one-sided", ba.oneSided, "fit as the paper does: only the base surface's samples pull (docs/bake.md)");
    bakeCmd->add_option("--adaptive", ba.adaptive, "tile sizes from the data: the error smaller tiles may add, x the diagonal (0: off)");
    bakeCmd->add_flag("--quiet", ba.quiet, "no progress bars");
    bakeCmd->add_flag("--table", ba.table, "the table: both routes, densities 4, 8, 16, on the dense meshes");
    bakeCmd->add_flag("--quick", ba.quick, "with --table: one mesh, densities 4 and 8");
    bakeCmd->add_option("--csv", ba.csv, "with --table: also write it as CSV");
    bakeCmd->add_option("--dense-dir", ba.denseDir, "with --table: folder of the dense meshes");
    bakeCmd->add_option("--skeleton-dir", ba.skeletonDir, "with --table: folder of their skeletons (<stem>.json)");
    // --threads after the command too (bake has its own, with the same meaning).
    for (CLI::App* sub : app.get_subcommands({}))
        if (sub != bakeCmd) sub->add_option("--threads", threads, threadsHelp);
    CLI11_PARSE(app, argc, argv);
    try {
        checkThreads(threads, "--threads");
        std::optional<tbb::global_control> threadLimit;
        if (threads > 0) threadLimit.emplace(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
        if (*demoCmd) return demo(quick);
        if (*tilesCmd) return tiles(ta, tilesOutput, mapOutput, mapSize);
        if (*evalCmd) return eval(ea);
        if (*tessCmd) return tessellateCommand(ts);
        if (*parityCmd) return runParity(pa);
        if (*renderCmd) return figures::renderCommand(ra);
        if (*mesoCmd) return mesoCommand(ma);
        if (*bakeCmd) return figures::bakeCommand(ba);
        if (*mapsCmd) {
            if (!mapsTable && !mapsSeams) throw ArgumentError("dispmap maps: give --table or --seams");
            if (!mapsImages.empty() && !mapsSeams) throw ArgumentError("dispmap maps: --images goes with --seams");
            if (mapsTable) figures::printMapsTable(std::cout, mta);
            if (mapsSeams) {
                figures::UvSeamsTableArgs ua;
                ua.dataDir = mta.dataDir;
                ua.quick = mta.quick;
                ua.device = mta.device;
                ua.images = mapsImages;
                figures::printUvSeamsTable(std::cout, ua);
            }
            return 0;
        }
        if (*benchCmd) {
            const figures::RenderTableArgs renderArgs{renderImages, renderCsv, renderFrames, renderWarmup, true, "", renderScene};
            if (only.empty() || only == "render") figures::checkRenderTableArgs(renderArgs); // bad arguments before any table runs
            // Every table, or the one --only names (then no timings either).
            // The Embree and cages tables take minutes and, for the bunny at isolation 6, about
            // 10 GB: only when --only names them.
            auto table = [&](const char* name, auto&& print) {
                const bool heavy = std::string_view(name) == "embree" || std::string_view(name) == "cages";
                if (only.empty() ? heavy : only != name) return;
                print();
                std::cout << "\n";
            };
            table("mips", [&] { figures::printMipTable(std::cout, csv); });
            table("normals", [&] { figures::printNormalTable(std::cout, normalsCsv); });
            table("isolation", [&] { figures::printIsolationTable(std::cout, isolationCsv); });
            table("swim", [&] { figures::printSwimFigure(std::cout, swimCsv); });
            table("tessellation", [&] { figures::printTessellationTable(std::cout, tessCsv); });
            table("edit", [&] { figures::printEditTable(std::cout, editCsv); });
            table("seams", [&] { figures::printSeamsTable(std::cout, seamsCsv); });
            table("render", [&] { figures::printRenderTable(std::cout, renderArgs); });
            table("cores", [&] { figures::printCoresTable(std::cout, cta); });
            eta.quick = cta.quick;
            table("embree", [&] { figures::printEmbreeTable(std::cout, eta); });
            gta.quick = cta.quick;
            table("cages", [&] { figures::printCagesTable(std::cout, gta); });
            if (!only.empty()) return 0;
            return figures::runBenchmarks(benchCmd->remaining());
        }
    } catch (const dispmap::Error& e) {
        std::cerr << "dispmap: " << e.what() << "\n";
        return 1;
    } catch (const std::bad_alloc&) {
        std::cerr << "dispmap: out of memory\n";
        return 1;
    } catch (const std::exception& e) { // a library's own exception (filesystem, JSON, TBB): a message, not an abort
        std::cerr << "dispmap: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
