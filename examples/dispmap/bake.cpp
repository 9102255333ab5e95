// `dispmap bake` and its table (bake.h).
#include "bake.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <vector>

#include <unistd.h>

#include <tbb/global_control.h>
#include <tbb/info.h>

#include "dispmap/bake/bake.h"
#include "dispmap/bake/simplify.h"
#include "dispmap/bake/skeleton.h"
#include "dispmap/io/mesh_writers.h"
#include "dispmap/io/png.h"
#include "dispmap/io/tile_file.h"
#include "dispmap/scene/scene.h"
#include "dispmap/surface/map_source.h"

namespace dispmap::figures {

namespace {

/// A progress bar on stderr, one line per stage, redrawn in place when stderr is a terminal.
struct ProgressBar {
    bool enabled = true, tty = isatty(2) != 0;
    std::string current, finished;
    void operator()(const std::string& stage, double f) {
        if (!enabled || (f >= 1.0 && stage == finished)) return; // a stage reports its end once
        if (f >= 1.0) finished = stage;
        if (stage != current && !current.empty() && tty) std::cerr << "\n";
        current = stage;
        if (!tty && f > 0.0 && f < 1.0) return; // in a log: start and end only
        const int width = 30, filled = static_cast<int>(std::lround(f * width));
        std::cerr << (tty ? "\r" : "") << "bake: " << std::left << std::setw(8) << stage << " [" << std::string(static_cast<std::size_t>(filled), '#')
                  << std::string(static_cast<std::size_t>(width - filled), '.') << "] " << std::setw(3) << std::lround(100 * f) << " %"
                  << (tty ? "" : "\n") << std::flush;
        if (f >= 1.0 && tty) {
            std::cerr << "\n";
            current.clear();
        }
    }
};

/// Blue (0) - green - red (1 % of the diagonal and more): the paper's Figure 14 range.
glm::u8vec3 heat(float percent) {
    const float x = std::clamp(percent, 0.0f, 1.0f);
    const float r = std::clamp(2.0f * x - 0.5f, 0.0f, 1.0f), g = 1.0f - std::abs(2.0f * x - 1.0f), b = std::clamp(1.0f - 2.0f * x, 0.0f, 1.0f);
    return glm::u8vec3(static_cast<std::uint8_t>(255.0f * r), static_cast<std::uint8_t>(255.0f * g), static_cast<std::uint8_t>(255.0f * b));
}

struct Route {
    MeshDescription icm;
    std::string name;
    double seconds = 0;
    nlohmann::json details;
};

/// The ICM by the skeleton route (`skeleton` given; `skeletonPath` names it in the report) or by
/// decimation to `baseFaces`.
Route baseMesh(const DenseMesh& dense, const RayScene& scene, const Skeleton* skeleton, const std::string& skeletonPath, int baseFaces) {
    Route r;
    const auto t0 = std::chrono::steady_clock::now();
    if (skeleton) {
        const Skeleton& sk = *skeleton;
        SkeletonReport sr;
        r.icm = skeletonControlMesh(dense, scene, sk, {}, &sr);
        r.name = "skeleton";
        r.details = {{"route", "skeleton"}, {"skeleton", skeletonPath}, {"joints", sk.joints.size()}, {"cuts", sr.cuts},
                     {"hinges", sr.hinges}, {"caps", sr.caps}};
    } else {
        SimplifyOptions so;
        so.targetFaces = baseFaces;
        SimplifyReport sr;
        r.icm = simplifiedControlMesh(dense, so, &sr);
        r.name = "simplify";
        r.details = {{"route", "simplify"}, {"target_faces", baseFaces}, {"faces", sr.faces},
                     {"dropped_nonmanifold", sr.droppedNonManifold}, {"dropped_components", sr.droppedComponents},
                     {"split_vertices", sr.splitVertices}};
    }
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return r;
}

BakeOptions bakeOptions(const BakeArgs& a) {
    BakeOptions o;
    o.density = a.density;
    o.fit.maxIterations = a.iterations;
    o.fit.samplesPerEdge = a.fitSamples;
    o.fit.normalWeight = a.normalWeight;
    o.fit.twoSided = !a.oneSided;
    o.adaptiveTolerance = a.adaptive;
    o.extract.shell = a.shell;
    return o;
}

/// A scene that renders the bake with `dispmap render`: the base mesh and tiles next to it, the
/// camera in front of the bounding box, uniform factors at the sample density.
Scene bakeScene(const BakeArgs& a, const DenseMesh& dense, const std::string& sceneDir) {
    Scene s;
    const auto rel = [&](const std::string& p) {
        return std::filesystem::relative(std::filesystem::absolute(p), std::filesystem::absolute(sceneDir)).string();
    };
    s.mesh = rel(a.output);
    s.displacement.tiles = rel(a.tiles);
    const glm::dvec3 c = 0.5 * (dense.lo + dense.hi);
    const double r = 0.5 * dense.diagonal();
    s.camera.target = c;
    s.camera.eye = c + glm::dvec3(0.0, 0.25 * r, 2.6 * r);
    s.camera.nearPlane = 0.05 * r;
    s.camera.farPlane = 10.0 * r;
    s.width = 640;
    s.height = 480;
    s.effects.tessValue = std::min(64.0, static_cast<double>(a.density));
    return s;
}

} // namespace

int bakeCommand(const BakeArgs& a) {
    if (a.table) {
        printBakeTable(std::cout, a);
        return 0;
    }
    // Every option is checked before the input is read (a scan takes seconds to load).
    if (a.input.empty()) throw ArgumentError("dispmap bake: give a dense mesh (OBJ, PLY or OFF)");
    if (a.skeleton.empty() == (a.baseFaces == 0))
        throw ArgumentError("dispmap bake: give --skeleton FILE or --base-faces N (one of them)");
    if (a.baseFaces != 0 && (a.baseFaces < 4 || a.baseFaces > 1000000))
        throw ArgumentError("dispmap bake: --base-faces " + std::to_string(a.baseFaces) + " is out of range (4 .. 1000000)");
    if (a.output.empty()) throw ArgumentError("dispmap bake: give -o BASE.obj (the tiles go to BASE.dmt unless --tiles says)");
    if (a.threads < 0) throw ArgumentError("dispmap bake: --threads must be >= 0 (0: all cores)");
    BakeArgs args = a;
    if (args.tiles.empty()) args.tiles = std::filesystem::path(a.output).replace_extension(".dmt").string();
    for (const auto& [path, what] : {std::pair{args.output, "OBJ mesh"}, std::pair{args.tiles, "tile file"},
                                     std::pair{args.report, "report"}, std::pair{args.heatmap, "PLY mesh"}, std::pair{args.scene, "scene"}})
        if (!path.empty()) {
            detail::checkOutputPath(path, what);
            const std::filesystem::path dir = std::filesystem::path(path).parent_path();
            if (!dir.empty() && !std::filesystem::is_directory(dir))
                throw ArgumentError("dispmap bake: cannot write " + std::string(what) + " '" + path + "': the folder '" + dir.string() +
                                    "' does not exist");
        }
    checkBakeOptions(bakeOptions(args));
    {
        // Two outputs at one path: the later write would replace the earlier silently.
        std::vector<std::pair<std::filesystem::path, std::string>> outs;
        for (const std::string& p : {args.output, args.tiles, args.report, args.heatmap, args.scene})
            if (!p.empty()) outs.emplace_back(std::filesystem::weakly_canonical(std::filesystem::absolute(p)), p);
        for (std::size_t i = 0; i < outs.size(); ++i)
            for (std::size_t k = i + 1; k < outs.size(); ++k)
                if (outs[i].first == outs[k].first)
                    throw ArgumentError("dispmap bake: '" + outs[i].second + "' and '" + outs[k].second + "' are the same file");
    }
    // The skeleton before the dense mesh: its errors cost nothing to find.
    std::optional<Skeleton> skeleton;
    if (!a.skeleton.empty()) skeleton = readSkeleton(a.skeleton);
    std::optional<tbb::global_control> threads;
    if (a.threads > 0) threads.emplace(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(a.threads));

    ProgressBar bar;
    bar.enabled = !a.quiet;
    const auto t0 = std::chrono::steady_clock::now();
    bar("read", 0.0);
    const DenseMesh dense = readDenseMesh(a.input);
    const RayScene scene(dense.positions, dense.triangles);
    const double readSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    bar("read", 1.0);
    bar("base", 0.0);
    Route route = baseMesh(dense, scene, skeleton ? &*skeleton : nullptr, a.skeleton, a.baseFaces);
    bar("base", 1.0);
    BakeOptions options = bakeOptions(args);
    options.progress = [&](const std::string& s, double f) { bar(s, f); };
    BakeResult res = bakeFromControlMesh(dense, scene, route.icm, options);
    res.report.threads = static_cast<int>(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
    res.report.stages.insert(res.report.stages.begin(), {{"read and BVH", readSeconds}, {"base mesh (" + route.name + ")", route.seconds}});

    // Everything to write is made first (a failure there writes nothing), then written: the
    // tiles before the mesh they belong to, the scene and report that name them last.
    const auto w0 = std::chrono::steady_clock::now();
    std::string sceneText;
    if (!args.scene.empty()) {
        const std::string dir = std::filesystem::path(args.scene).parent_path().string();
        sceneText = toJson(bakeScene(args, dense, dir.empty() ? "." : dir));
    }
    std::vector<glm::u8vec3> colours(res.resultError.size());
    for (std::size_t i = 0; i < colours.size(); ++i) colours[i] = heat(res.resultError[i]);
    saveTiles(res.tiles, args.tiles);
    writeObj(res.base, args.output);
    if (!args.heatmap.empty()) writePly(res.result, args.heatmap, &colours);
    if (!sceneText.empty()) detail::writeFileAtomically(args.scene, std::vector<unsigned char>(sceneText.begin(), sceneText.end()), "scene");
    res.report.stages.push_back({"writing", std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count()});
    nlohmann::json j = bakeReportJson(res.report);
    j["base"]["route"] = route.details;
    std::error_code ec;
    j["files"] = {{"base", args.output}, {"tiles", args.tiles}, {"base_bytes", std::filesystem::file_size(args.output, ec)},
                  {"tile_bytes", tileFileBytes(res.tiles)}};
    // Paths need not be UTF-8; JSON must be: invalid bytes become U+FFFD.
    const std::string reportText = j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
    if (!args.report.empty())
        detail::writeFileAtomically(args.report, std::vector<unsigned char>(reportText.begin(), reportText.end()), "report");
    const BakeReport& r = res.report;
    std::cout << std::setprecision(4) << "baked " << a.input << " (" << r.inputVertices << " vertices, " << r.inputTriangles
              << " triangles) by " << route.name << ": ICM " << r.icmFaces << " faces -> base " << r.baseFaces << " quads, "
              << r.density << " x " << r.density << " samples per face\n";
    if (route.name == "simplify" && r.icmFaces > 2 * a.baseFaces)
        std::cout << "  (the decimation stopped at " << r.icmFaces << " faces of the " << a.baseFaces
                  << " asked for: meshoptimizer keeps the scan's borders and topology)\n";
    std::cout << "  RMS " << r.rmsDenseToResult << " % (dense -> result), " << r.rmsResultToDense << " % (result -> dense); max "
              << r.maxDenseToResult << " %, " << r.maxResultToDense << " % of the diagonal\n"
              << "  compression " << r.compressionRatio << " (paper's count), " << r.fileCompressionRatio << " (our files); "
              << r.extract.misses << " misses, " << r.extract.foldovers << " fold-overs of " << r.extract.samples << " samples\n"
              << "  " << j["seconds_total"].get<double>() << " s on " << r.threads << " threads, peak " << r.peakRssMiB << " MiB\n"
              << "wrote " << args.tiles << ", " << args.output;
    for (const std::string& p : {args.heatmap, args.scene, args.report})
        if (!p.empty()) std::cout << ", " << p;
    std::cout << "\n";
    return 0;
}

namespace {

struct TableInput {
    std::string name;
    std::shared_ptr<const DenseMesh> dense;
    std::string skeleton; // "" = none
};

/// Our own dense mesh with a known answer: Spot with the brick height field, tessellated finely.
DenseMesh ownDenseMesh(const std::string& dataDir, int factor) {
    const ControlMesh mesh = ControlMesh::fromObjFile(dataDir + "/spot_control_mesh.obj");
    auto img = std::make_shared<HeightImage>(readHeightPng(dataDir + "/skimage_brick.png"));
    const TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 5), imageSource(mesh, img, 0.02, -0.01, /*wrap=*/true));
    const BaseSurface base(mesh);
    const DisplacedSurface surface(base, tiles);
    TessellateOptions to;
    to.spacing = Spacing::Integer;
    return denseMeshOf(Tessellator(surface, uniformTessFactors(base, factor), to).tessellate(),
                       "spot + bricks, factor " + std::to_string(factor));
}

} // namespace

void printBakeTable(std::ostream& out, const BakeArgs& a) {
    std::vector<TableInput> inputs;
    const std::string denseDir = a.denseDir;
    for (const char* f : {"bunny_npm_lowres.obj", "cgal_fandisk.off", "cgal_bunny00.off"}) {
        const std::string p = denseDir + "/" + f;
        if (!std::filesystem::exists(p)) continue;
        const std::string stem = std::filesystem::path(f).stem().string();
        const std::string sk = a.skeletonDir + "/" + stem + ".json";
        inputs.push_back({stem, std::make_shared<DenseMesh>(readDenseMesh(p)), std::filesystem::exists(sk) ? sk : ""});
        if (a.quick) break;
    }
    if (!a.quick) inputs.push_back({"spot+bricks", std::make_shared<DenseMesh>(ownDenseMesh(a.dataDir, 40)), ""});
    if (inputs.empty()) throw ArgumentError("dispmap bake --table: no dense meshes in '" + denseDir + "' (--dense-dir)");

    std::ostringstream csv;
    if (!a.csv.empty()) {
        detail::checkOutputPath(a.csv, "CSV table");
        csv << "model,vertices,route,icm_faces,base_faces,density,fit_iterations,fit_rms_percent,rms_dense_to_result,max_dense_to_result,"
               "rms_result_to_dense,max_result_to_dense,compression_paper,compression_files,misses,foldovers,s_base,s_fit,s_rays,s_tiles,"
               "s_measure,s_total,peak_rss_mib\n";
    }
    out << "Baking: dense mesh -> base mesh + tiles (dispmap bake --table), " << tbb::info::default_concurrency()
        << " threads. Errors in % of the bounding-box diagonal:\n"
        << "d->r from every dense vertex to the result tessellated at 2 x density, r->d from every result vertex to the dense mesh.\n"
        << "Compression: the paper's count (input 12 V + 12 F bytes over 12 V_base + 4 x ICM indices + 4 F_base (sd+1)^2) and our files\n"
        << "(tile file with overlap and mips + binary base mesh). Seconds per stage: base mesh, fitting (interpolation, CC step,\n"
        << "progressive fitting), rays, tile fit, the total of those (what the paper times), and the measurement.\n\n";
    out << std::left << std::setw(18) << "model" << std::setw(9) << "route" << std::right << std::setw(6) << "ICM" << std::setw(6) << "base"
        << std::setw(4) << "sd" << std::setw(4) << "it" << std::setw(8) << "fitRMS" << std::setw(8) << "RMSd>r" << std::setw(8) << "maxd>r"
        << std::setw(8) << "RMSr>d" << std::setw(8) << "maxr>d" << std::setw(8) << "compr" << std::setw(8) << "files" << std::setw(7)
        << "miss" << std::setw(6) << "fold" << std::setw(7) << "base" << std::setw(7) << "fit" << std::setw(7) << "rays" << std::setw(7)
        << "tiles" << std::setw(8) << "total" << std::setw(8) << "meas" << std::setw(7) << "MiB" << "\n";
    const std::vector<int> densities = a.quick ? std::vector<int>{4, 8} : std::vector<int>{4, 8, 16};
    for (const TableInput& in : inputs) {
        const DenseMesh& dense = *in.dense;
        const RayScene scene(dense.positions, dense.triangles);
        std::vector<Route> routes;
        int faces = 256;
        if (!in.skeleton.empty()) {
            const Skeleton sk = readSkeleton(in.skeleton);
            routes.push_back(baseMesh(dense, scene, &sk, in.skeleton, 0));
            faces = static_cast<int>(routes.back().icm.faceSizes.size());
        }
        routes.push_back(baseMesh(dense, scene, nullptr, "", faces)); // simplification at the skeleton's face count (or 256)
        if (!a.quick) {
            routes.push_back(baseMesh(dense, scene, nullptr, "", std::max(16, faces / 4))); // a quarter: the paper's compression ratios
            if (dense.positions.size() > 100000) routes.push_back(baseMesh(dense, scene, nullptr, "", 1024));
        }
        for (const Route& r : routes) {
            for (int sd : densities) {
                BakeArgs ba = a;
                ba.density = sd;
                const BakeResult res = bakeFromControlMesh(dense, scene, r.icm, bakeOptions(ba));
                const BakeReport& rep = res.report;
                auto sec = [&](std::size_t i) { return i < rep.stages.size() ? rep.stages[i].seconds : 0.0; };
                const double fit = sec(0) + sec(1), total = r.seconds + fit + sec(2) + sec(3); // the bake, not the measurement
                const int its = static_cast<int>(rep.fit.iterations.size()) - 1;
                const double fitRms = rep.fit.iterations.empty() ? 0.0 : rep.fit.result().rmsPercent;
                out << std::left << std::setw(18) << in.name << std::setw(9) << r.name << std::right << std::setw(6) << rep.icmFaces
                    << std::setw(6) << rep.baseFaces << std::setw(4) << sd << std::setw(4) << its << std::fixed << std::setprecision(3)
                    << std::setw(8) << fitRms << std::setw(8) << rep.rmsDenseToResult << std::setw(8) << rep.maxDenseToResult << std::setw(8)
                    << rep.rmsResultToDense << std::setw(8) << rep.maxResultToDense << std::setprecision(2) << std::setw(8)
                    << rep.compressionRatio << std::setw(8) << rep.fileCompressionRatio << std::setw(7) << rep.extract.misses << std::setw(6)
                    << rep.extract.foldovers << std::setw(7) << r.seconds << std::setw(7) << fit << std::setw(7) << sec(2) << std::setw(7)
                    << sec(3) << std::setw(8) << total << std::setw(8) << sec(4) << std::setprecision(0) << std::setw(7) << rep.peakRssMiB
                    << std::defaultfloat << "\n";
                if (!a.csv.empty())
                    csv << in.name << ',' << dense.positions.size() << ',' << r.name << ',' << rep.icmFaces << ',' << rep.baseFaces << ','
                        << sd << ',' << its << ',' << fitRms << ',' << rep.rmsDenseToResult << ',' << rep.maxDenseToResult << ','
                        << rep.rmsResultToDense << ',' << rep.maxResultToDense << ',' << rep.compressionRatio << ','
                        << rep.fileCompressionRatio << ',' << rep.extract.misses << ',' << rep.extract.foldovers << ',' << r.seconds << ','
                        << fit << ',' << sec(2) << ',' << sec(3) << ',' << sec(4) << ',' << total << ',' << rep.peakRssMiB << '\n';
            }
        }
        out << "  (" << in.name << ": " << dense.positions.size() << " vertices, " << dense.triangles.size() << " triangles)\n";
    }
    if (!a.csv.empty()) {
        const std::string text = csv.str();
        detail::writeFileAtomically(a.csv, std::vector<unsigned char>(text.begin(), text.end()), "CSV table");
    }
    out << "\nThe paper's Table 2 (Huang & Feng 2017; skeleton route, GTX 570; RMS from the input to the result):\n"
        << "  bunny     124k vertices, ICM 144 faces:  sd 4: RMS 0.225 %, compression 86.7; sd 8: 0.123 %, 29.6; sd 16: 0.070 %, 8.6;"
           " total 13.7 / 17.1 / 29.8 s\n"
        << "  armadillo 173k vertices, ICM 256 faces:  sd 4: RMS 0.236 %, compression 68.7; sd 8: 0.118 %, 23.4; sd 16: 0.071 %, 6.8;"
           " total 25.8 / 34.4 / 66.6 s\n"
        << "  venus      50k vertices: sd 16: 0.046 %; neptune 2M vertices: sd 16: 0.023 %\n";

    // The knobs of the fit and of the tile sizes, one at a time, on one mesh (the bunny when
    // it is there, with its skeleton when it has one).
    const TableInput* pick = &inputs.front();
    for (const TableInput& t : inputs)
        if (t.name == "cgal_bunny00") pick = &t;
    const TableInput& in = *pick;
    const DenseMesh& dense = *in.dense;
    const RayScene scene(dense.positions, dense.triangles);
    std::optional<Skeleton> sk;
    if (!in.skeleton.empty()) sk = readSkeleton(in.skeleton);
    const Route route = baseMesh(dense, scene, sk ? &*sk : nullptr, in.skeleton, 256);
    struct Knob {
        std::string name;
        std::function<void(BakeOptions&)> set;
    };
    const std::vector<Knob> knobs = {
        {"paper: one-sided, 5 iterations", [](BakeOptions& o) { o.fit.twoSided = false; o.fit.maxIterations = 5; }},
        {"one-sided, 8 iterations", [](BakeOptions& o) { o.fit.twoSided = false; o.fit.maxIterations = 8; }},
        {"one-sided, 30 iterations", [](BakeOptions& o) { o.fit.twoSided = false; }},
        {"two-sided, 5 iterations", [](BakeOptions& o) { o.fit.maxIterations = 5; }},
        {"two-sided, 8 iterations", [](BakeOptions& o) { o.fit.maxIterations = 8; }},
        {"two-sided, 30 iterations (default)", [](BakeOptions&) {}},
        {"no interpolation step", [](BakeOptions& o) { o.fit.interpolationSteps = 0; }},
        {"fit samples 4 per edge", [](BakeOptions& o) { o.fit.samplesPerEdge = 4; }},
        {"fit samples 16 per edge", [](BakeOptions& o) { o.fit.samplesPerEdge = 16; }},
        {"sd 16, uniform tiles", [](BakeOptions& o) { o.density = 16; }},
        {"sd 16, adaptive 1e-4", [](BakeOptions& o) { o.density = 16; o.adaptiveTolerance = 1e-4; }},
        {"sd 16, adaptive 3e-4", [](BakeOptions& o) { o.density = 16; o.adaptiveTolerance = 3e-4; }},
        {"sd 16, adaptive 1e-3", [](BakeOptions& o) { o.density = 16; o.adaptiveTolerance = 1e-3; }},
    };
    out << "\nWhat each knob costs (" << in.name << ", " << route.name << " route, ICM " << route.icm.faceSizes.size()
        << " faces, sd 8 unless named; adaptive tolerances in units of the diagonal):\n"
        << std::left << std::setw(36) << "setting" << std::right << std::setw(4) << "it" << std::setw(8) << "fitRMS" << std::setw(8)
        << "RMSd>r" << std::setw(8) << "maxd>r" << std::setw(8) << "RMSr>d" << std::setw(8) << "maxr>d" << std::setw(9) << "samples"
        << std::setw(8) << "compr" << std::setw(7) << "fit s" << std::setw(8) << "total s" << "\n";
    for (const Knob& k : knobs) {
        if (a.quick && k.name.find("fit samples") != std::string::npos) continue;
        BakeArgs ba = a;
        ba.density = 8;
        BakeOptions o = bakeOptions(ba);
        k.set(o);
        const BakeResult res = bakeFromControlMesh(dense, scene, route.icm, o);
        const BakeReport& rep = res.report;
        auto sec = [&](std::size_t i) { return i < rep.stages.size() ? rep.stages[i].seconds : 0.0; };
        out << std::left << std::setw(36) << k.name << std::right << std::setw(4) << static_cast<int>(rep.fit.iterations.size()) - 1
            << std::fixed << std::setprecision(3) << std::setw(8) << rep.fit.result().rmsPercent << std::setw(8)
            << rep.rmsDenseToResult << std::setw(8) << rep.maxDenseToResult << std::setw(8) << rep.rmsResultToDense << std::setw(8)
            << rep.maxResultToDense << std::setprecision(0) << std::setw(9) << rep.tileTexels << std::setprecision(2) << std::setw(8)
            << rep.compressionRatio << std::setw(7) << sec(0) + sec(1) << std::setw(8) << route.seconds + sec(0) + sec(1) + sec(2) + sec(3)
            << std::defaultfloat << "\n";
    }
}

} // namespace dispmap::figures
