// dispmap: the command-line program.
//   dispmap demo                      build the embedded default tile set, print its figures
//   dispmap tiles --mesh M.obj ...    build (or --load) a tile set, print statistics, save it
//   dispmap bench [gbench args]       the benchmark table and the timings
//   dispmap parity                    every kernel on the GPU (lavapipe by default) against C++
#include <CLI/CLI.hpp>

#include <iostream>
#include <memory>
#include <vector>

#include "dispmap/height_image.h"
#include "dispmap/tile_builder.h"
#include "dispmap/tile_file.h"
#include "dispmap/vulkan/context.h"
#include "figures.h"
#include "parity.h"

using namespace dispmap;

namespace {
int demo(bool quick) {
    ControlMesh mesh = figures::defaultMesh();
    BuildReport rep;
    TileSet ts = buildTiles(mesh, uniformTileSizes(mesh, 5), figures::defaultDisplacement, {}, &rep);
    figures::printTileStats(std::cout, "Default scene (embedded box with a pentagon and a triangle, k = 5):", ts, &rep);
    std::cout << "\n";
    figures::printMipTable(std::cout, "");
    std::cout << "\nTimings (Google Benchmark" << (quick ? ", short runs" : "") << "):\n" << std::flush;
    std::vector<std::string> flags;
    if (quick) flags.push_back("--benchmark_min_time=0.05");
    return figures::runBenchmarks(flags);
}

struct TilesArgs {
    std::string mesh, height, load, output, filter = "haar", function = "waves";
    int k = 4;
    double scale = 0.1, offset = 0.0;
    bool wrap = false;
};

int tiles(const TilesArgs& a) {
    if (!a.load.empty()) {
        TileSet ts = loadTiles(a.load);
        if (!a.mesh.empty()) {
            ControlMesh mesh = ControlMesh::fromObjFile(a.mesh);
            if (topologyHash(mesh) != ts.topologyHash || mesh.ptexFaceCount() != ts.tileCount())
                throw ArgumentError(a.load + " was built for another mesh than " + a.mesh);
        }
        figures::printTileStats(std::cout, "Tile file " + a.load + ":", ts, nullptr);
        return 0;
    }
    if (a.mesh.empty()) throw ArgumentError("tiles: give --mesh (with --height or --function) or --load");
    ControlMesh mesh = ControlMesh::fromObjFile(a.mesh);
    DisplacementFunction source;
    if (!a.height.empty()) {
        auto img = std::make_shared<HeightImage>(readHeightPng(a.height));
        source = imageSource(mesh, img, a.scale, a.offset, a.wrap);
    } else if (a.function == "waves") {
        const double s = a.scale;
        source = [s](int f, double u, double v) { return s * figures::defaultDisplacement(f, u, v) / 0.07; };
    } else if (a.function == "zero") {
        source = [](int, double, double) { return 0.0; };
    } else {
        throw ArgumentError("tiles: unknown --function '" + a.function + "' (waves, zero)");
    }
    BuildOptions o;
    if (a.filter == "haar")
        o.filter = MipFilter::Haar;
    else if (a.filter == "bwavelet")
        o.filter = MipFilter::BWavelet;
    else
        throw ArgumentError("tiles: unknown --filter '" + a.filter + "' (haar, bwavelet)");
    BuildReport rep;
    TileSet ts = buildTiles(mesh, uniformTileSizes(mesh, a.k), source, o, &rep);
    figures::printTileStats(std::cout, "Tiles of " + a.mesh + ":", ts, &rep);
    if (!a.output.empty()) {
        saveTiles(ts, a.output);
        std::cout << "  saved " << a.output << "\n";
    }
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
} // namespace

int main(int argc, char** argv) {
    CLI::App app{"dispmap: analytic displacement mapping on Catmull-Clark surfaces"};
    app.require_subcommand(1);
    bool quick = false;
    auto* demoCmd = app.add_subcommand("demo", "build the embedded default tile set and print its figures");
    demoCmd->add_flag("--quick", quick, "short benchmark runs");
    TilesArgs ta;
    auto* tilesCmd = app.add_subcommand("tiles", "build a tile set from a mesh and a displacement source");
    tilesCmd->add_option("--mesh", ta.mesh, "control mesh (OBJ, OpenSubdiv tags)");
    tilesCmd->add_option("--height", ta.height, "UV-mapped height image (8/16-bit greyscale PNG)");
    tilesCmd->add_option("--scale", ta.scale, "displacement = offset + scale * height (or the function's amplitude)");
    tilesCmd->add_option("--offset", ta.offset, "displacement offset");
    tilesCmd->add_flag("--wrap", ta.wrap, "wrap texture coordinates outside [0, 1]");
    tilesCmd->add_option("--function", ta.function, "procedural source when no image: waves, zero");
    tilesCmd->add_option("-k,--size", ta.k, "log2 tile size of quads (sub-faces of non-quads get k - 1)");
    tilesCmd->add_option("--filter", ta.filter, "mip filter: haar, bwavelet");
    tilesCmd->add_option("-o,--output", ta.output, "write the tile file");
    tilesCmd->add_option("--load", ta.load, "read a tile file instead (with --mesh: check it matches)");
    auto* benchCmd = app.add_subcommand("bench", "mip accuracy table and timings (Google Benchmark flags pass through)");
    std::string csv;
    benchCmd->add_option("--csv", csv, "also write the mip table as CSV");
    std::string normalsCsv;
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
    CLI11_PARSE(app, argc, argv);
    try {
        if (*demoCmd) return demo(quick);
        if (*tilesCmd) return tiles(ta);
        if (*parityCmd) return runParity(pa);
        if (*benchCmd) {
            figures::printMipTable(std::cout, csv);
            std::cout << "\n";
            figures::printNormalTable(std::cout, normalsCsv);
            std::cout << "\n";
            return figures::runBenchmarks(benchCmd->remaining());
        }
    } catch (const dispmap::Error& e) {
        std::cerr << "dispmap: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
