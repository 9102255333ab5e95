// dispmap: the command-line program.
//   dispmap demo                      build the embedded default tile set, print its figures
//   dispmap tiles --mesh M.obj ...    build (or --load) a tile set, print statistics, save it
//   dispmap bench [gbench args]       the benchmark table and the timings
#include <CLI/CLI.hpp>

#include <iostream>
#include <memory>
#include <vector>

#include "dispmap/height_image.h"
#include "dispmap/tile_builder.h"
#include "dispmap/tile_file.h"
#include "figures.h"

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
    benchCmd->allow_extras();
    CLI11_PARSE(app, argc, argv);
    try {
        if (*demoCmd) return demo(quick);
        if (*tilesCmd) return tiles(ta);
        if (*benchCmd) {
            figures::printMipTable(std::cout, csv);
            return figures::runBenchmarks(benchCmd->remaining());
        }
    } catch (const dispmap::Error& e) {
        std::cerr << "dispmap: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
