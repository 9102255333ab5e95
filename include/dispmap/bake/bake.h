#pragma once
// Baking: a dense mesh (a scan, a sculpt) to a Catmull-Clark base mesh plus displacement tiles
// (Huang & Feng 2017, "Efficient skeleton-guided displaced subdivision surfaces"). The stages:
//   base mesh (ICM)   bake/simplify.h (decimation) or bake/skeleton.h (cuts, hinges, pipes)
//   -> fitting        bake/fit.h: progressive interpolation, one Catmull-Clark step (IBM),
//                     progressive fitting to the dense mesh (OBM)
//   -> extraction     bake/extract.h: rays along +-N from every tile sample (Embree)
//   -> tiles          surface/tile_builder.h: the biquadratic fit with the Doo-Sabin corners
//                     and mips, as for any other displacement source
//   -> measurement    the displaced surface tessellated at twice the density; distances from
//                     every dense vertex to it and from every one of its vertices to the dense
//                     mesh (Embree closest points), RMS and max in % of the bounding-box diagonal
// bakeFromControlMesh runs everything after the ICM; docs/bake.md describes the whole.
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <sys/resource.h>

#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include "dispmap/bake/dense_mesh.h"
#include "dispmap/bake/extract.h"
#include "dispmap/bake/fit.h"
#include "dispmap/bake/ray_scene.h"
#include "dispmap/io/tile_file.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/tessellator.h"
#include "dispmap/surface/tile_builder.h"

namespace dispmap {

struct BakeOptions {
    int density = 16;           ///< samples per base face edge (the paper's sd): tiles of k = log2(density)
    FitOptions fit;             ///< progressive interpolation and fitting
    ExtractOptions extract;     ///< the rays' shell
    /// Per-face tile sizes from the data (adaptiveTileSizes): 0 = every tile at the density;
    /// else the largest error the smaller tiles may add, a fraction of the diagonal.
    double adaptiveTolerance = 0;
    int isolation = 6;          ///< the base surface's isolation (BaseSurfaceOptions)
    bool gregoryEndCaps = true; ///< the base surface's end caps (BaseSurfaceOptions): bake over the base the tiles will lie on
    MipFilter filter = MipFilter::Haar;
    int measureFactor = 0;      ///< tessellation factor of the measured result; 0: 2 x density (at most 64, and kMaxMeasureVertices)
    bool measure = true;        ///< measure the errors (the slowest stage on large meshes)
    /// Called with (stage, fraction done in [0, 1]) for progress bars: from the calling thread or
    /// a worker thread, one call at a time.
    std::function<void(const std::string&, double)> progress;
};

struct BakeStage {
    std::string name;
    double seconds = 0;
};

struct BakeReport {
    std::string input;
    std::uint64_t inputVertices = 0, inputTriangles = 0, degenerateDropped = 0, weldedVertices = 0, unusedVertices = 0;
    double diagonal = 0;
    int icmVertices = 0, icmFaces = 0, baseVertices = 0, baseFaces = 0, density = 0;
    double tileTexels = 0; ///< samples over all tiles (less than baseFaces x density^2 with adaptive sizes)
    int measureFactor = 0; ///< the tessellation factor of the measured result
    FitReport fit;
    ExtractReport extract;
    BuildReport tiles;
    // errors, % of the diagonal (dense -> result: from every dense vertex; result -> dense: from
    // every vertex of the result tessellated at measureFactor)
    double rmsDenseToResult = 0, maxDenseToResult = 0, rmsResultToDense = 0, maxResultToDense = 0;
    std::uint64_t resultTriangles = 0;
    // sizes (bytes) as the paper's §4.2 counts them: input 12 V + 12 F; ours B + M with
    // B = 12 V_base + 4 sum(ICM face sizes), M = F_base (sd + 1)^2 x 4
    double inputBytes = 0, paperBytes = 0, compressionRatio = 0;
    // our own files: the tile file and the base mesh as binary (12 V + 16 F)
    double tileFileBytes = 0, baseBinaryBytes = 0, fileCompressionRatio = 0;
    std::vector<BakeStage> stages;
    double peakRssMiB = 0;
    int threads = 0;
};

struct BakeResult {
    MeshDescription icm, base; ///< the initial control mesh and the optimised base mesh (OBM)
    TileSet tiles;
    BakeReport report;
    TriangleMesh result;              ///< the displaced surface as measured (empty if !measure)
    std::vector<float> resultError;   ///< per result vertex: distance to the dense mesh, % of the diagonal
};

/// A tessellated surface (TriangleMesh) as a dense mesh: dispmap's own dense inputs with a
/// known answer (tests, the bake table). Throws as makeDenseMesh.
inline DenseMesh denseMeshOf(const TriangleMesh& t, std::string name) {
    std::vector<std::array<std::uint64_t, 3>> tris(t.triangles.size());
    for (std::size_t i = 0; i < tris.size(); ++i)
        for (int c = 0; c < 3; ++c) tris[i][static_cast<std::size_t>(c)] = static_cast<std::uint64_t>(t.triangles[i][c]);
    return makeDenseMesh(std::move(name), {t.positions.begin(), t.positions.end()}, tris, tris.size());
}

/// Most vertices of the measured tessellation (~200 bytes each with its BVH): the factor is
/// lowered until the result fits.
inline constexpr std::uint64_t kMaxMeasureVertices = std::uint64_t{8} << 20;

/// Peak resident memory of this process so far (getrusage), MiB.
inline double peakRssMiB() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<double>(u.ru_maxrss) / 1024.0;
}

/// Throws ArgumentError naming the first option out of range (a program checks them before it
/// reads anything; bakeFromControlMesh checks them again).
inline void checkBakeOptions(const BakeOptions& o) {
    const int k = static_cast<int>(std::lround(std::log2(std::max(o.density, 1))));
    if (o.density < 2 || (1 << k) != o.density || k > kMaxTileLog2)
        throw ArgumentError("bake: the density must be a power of two in [2, " + std::to_string(1 << kMaxTileLog2) + "], not " +
                            std::to_string(o.density));
    if (o.measureFactor < 0 || o.measureFactor > 64) throw ArgumentError("bake: the measure factor must be in [0, 64]");
    if (o.fit.samplesPerEdge < 1 || o.fit.samplesPerEdge > 64)
        throw ArgumentError("bake: fitting samples per edge must be in [1, 64], not " + std::to_string(o.fit.samplesPerEdge));
    if (o.fit.maxIterations < 0 || o.fit.maxIterations > 1000)
        throw ArgumentError("bake: fitting iterations must be in [0, 1000], not " + std::to_string(o.fit.maxIterations));
    if (o.fit.interpolationSteps < 0 || o.fit.interpolationSteps > 100) throw ArgumentError("bake: interpolation steps must be in [0, 100]");
    if (!(o.fit.normalWeight >= 0.0 && o.fit.normalWeight <= 10.0)) throw ArgumentError("bake: the normal weight must be in [0, 10]");
    if (!(o.extract.shell > 0.0 && o.extract.shell <= 10.0)) throw ArgumentError("bake: the shell must be in (0, 10] diagonals");
    if (!(o.adaptiveTolerance >= 0.0 && o.adaptiveTolerance <= 1.0)) throw ArgumentError("bake: the adaptive tolerance must be in [0, 1]");
    if (o.isolation < 1 || o.isolation > 10) throw ArgumentError("bake: the isolation level must be in [1, 10]");
}

/// The stages after the ICM (see the header). `dense` is the mesh `scene` was built on. Throws
/// ArgumentError for options out of range, MeshError for an ICM that ControlMesh refuses.
inline BakeResult bakeFromControlMesh(const DenseMesh& dense, const RayScene& scene, MeshDescription icm,
                                      const BakeOptions& options) {
    checkBakeOptions(options);
    const int k = static_cast<int>(std::lround(std::log2(options.density)));
    BakeResult res;
    BakeReport& rep = res.report;
    rep.input = dense.name;
    rep.inputVertices = dense.positions.size();
    rep.inputTriangles = dense.triangles.size();
    rep.degenerateDropped = dense.stats.degenerateDropped;
    rep.weldedVertices = dense.stats.weldedVertices;
    rep.unusedVertices = dense.stats.unusedVertices;
    rep.diagonal = dense.diagonal();
    rep.density = options.density;
    auto clock = std::chrono::steady_clock::now();
    auto stage = [&](const char* name) {
        const auto now = std::chrono::steady_clock::now();
        rep.stages.push_back({name, std::chrono::duration<double>(now - clock).count()});
        clock = now;
    };
    auto progress = [&](const char* name, double f) {
        if (options.progress) options.progress(name, f);
    };

    // Fitting (progressive interpolation, one Catmull-Clark step, progressive fitting).
    progress("fit", 0.0);
    res.icm = std::move(icm);
    rep.icmVertices = static_cast<int>(res.icm.positions.size());
    rep.icmFaces = static_cast<int>(res.icm.faceSizes.size());
    const MeshDescription interpolated = progressiveInterpolation(res.icm, options.fit.interpolationSteps, options.fit.stencilIsolation);
    const MeshDescription ibm = catmullClarkStep(interpolated);
    stage("base mesh (interpolation, Catmull-Clark step)");
    const DenseVertexIndex index(dense, options.fit.normalWeight);
    res.base = fitToDense(ibm, dense, scene, index, options.fit, &rep.fit, [&](double f) { progress("fit", f); });
    res.base.name = dense.name + " (baked base mesh)";
    rep.baseVertices = static_cast<int>(res.base.positions.size());
    rep.baseFaces = static_cast<int>(res.base.faceSizes.size());
    stage("fitting");
    progress("fit", 1.0);

    // Extraction along the base normals.
    progress("rays", 0.0);
    const ControlMesh mesh(res.base);
    std::vector<int> ks = uniformTileSizes(mesh, k);
    {
        // The tile file the full density would make must be one saveTiles can write.
        std::uint64_t floats = 0;
        for (int kt : ks) floats += Tile::totalTexels(kt);
        if (tileFileBytes(ks.size(), floats) > detail::kMaxTileFileBytes)
            throw ArgumentError("bake: " + std::to_string(ks.size()) + " tiles of " + std::to_string(options.density) + " x " +
                                std::to_string(options.density) + " samples would take " + std::to_string(tileFileBytes(ks.size(), floats) >> 20) +
                                " MiB, more than a tile file may hold: fewer base faces or a lower density");
    }
    BaseSurfaceOptions bo;
    bo.isolationLevel = options.isolation;
    bo.gregoryEndCaps = options.gregoryEndCaps;
    const BaseSurface base(mesh, bo);
    auto samples = std::make_shared<std::vector<std::vector<double>>>(
        extractSamples(base, ks, scene, rep.diagonal, options.extract, &rep.extract, [&](double f) { progress("rays", f); }));
    if (options.adaptiveTolerance > 0.0) {
        for (int f = 0; f < mesh.base().GetNumFaces(); ++f)
            if (mesh.base().GetFaceVertices(f).size() != 4)
                throw ArgumentError("bake: adaptive tile sizes need an all-quad base mesh (face " + std::to_string(f + 1) + " is not)");
        ks = adaptiveTileSizes(*samples, k, options.adaptiveTolerance * rep.diagonal);
    }
    for (int kt : ks) rep.tileTexels += static_cast<double>(1 << kt) * static_cast<double>(1 << kt);
    stage("extraction (rays)");
    progress("rays", 1.0);
    BuildOptions build;
    build.filter = options.filter;
    res.tiles = buildTiles(mesh, ks, sampledSource(samples, ks), build, &rep.tiles);
    stage("tile fit");

    // Sizes (§4.2).
    rep.inputBytes = 12.0 * static_cast<double>(rep.inputVertices) + 12.0 * static_cast<double>(rep.inputTriangles);
    double icmIndices = 0;
    for (int n : res.icm.faceSizes) icmIndices += n;
    double texels = 0; // (sd + 1)^2 per face, the paper's count, at each tile's own size
    for (int kt : ks) texels += ((1 << kt) + 1.0) * ((1 << kt) + 1.0);
    rep.paperBytes = 12.0 * rep.baseVertices + 4.0 * icmIndices + 4.0 * texels;
    rep.compressionRatio = rep.inputBytes / rep.paperBytes;
    rep.tileFileBytes = static_cast<double>(tileFileBytes(res.tiles));
    rep.baseBinaryBytes = 12.0 * rep.baseVertices + 16.0 * rep.baseFaces;
    rep.fileCompressionRatio = rep.inputBytes / (rep.tileFileBytes + rep.baseBinaryBytes);

    if (options.measure) {
        progress("measure", 0.0);
        DisplacedSurfaceOptions dso;
        dso.autoSamples = 2; // auto normals are not used here: the cheapest analysis
        const DisplacedSurface surface(base, res.tiles, dso);
        TessellateOptions to;
        to.spacing = Spacing::Integer;
        // Twice the density, at most 64 (the hardware's limit) and at most kMaxMeasureVertices.
        int factor = options.measureFactor > 0 ? options.measureFactor : std::min(64, 2 * options.density);
        while (factor > 1 && static_cast<double>(rep.baseFaces) * (factor + 1.0) * (factor + 1.0) > static_cast<double>(kMaxMeasureVertices))
            --factor;
        rep.measureFactor = factor;
        res.result = Tessellator(surface, uniformTessFactors(base, factor), to).tessellate();
        rep.resultTriangles = res.result.triangles.size();
        std::vector<glm::vec3> rp(res.result.positions.size());
        for (std::size_t i = 0; i < rp.size(); ++i) rp[i] = glm::vec3(res.result.positions[i]);
        std::vector<glm::uvec3> rt(res.result.triangles.size());
        for (std::size_t i = 0; i < rt.size(); ++i) rt[i] = glm::uvec3(res.result.triangles[i]);
        const RayScene resultScene(rp, rt);
        std::vector<float> toResult(dense.positions.size());
        res.resultError.assign(rp.size(), 0.0f);
        const double unit = 100.0 / rep.diagonal;
        // Progress every 2 % of the queries, from whichever thread crosses the mark.
        const std::size_t queries = toResult.size() + rp.size();
        std::atomic<std::size_t> done{0};
        std::mutex progressMutex;
        auto advance = [&](std::size_t n) {
            const std::size_t after = done += n, before = after - n;
            if (after * 50 / queries != before * 50 / queries) {
                const std::lock_guard<std::mutex> lock(progressMutex);
                progress("measure", static_cast<double>(after) / static_cast<double>(queries));
            }
        };
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, toResult.size(), 1024), [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i)
                toResult[i] = static_cast<float>(static_cast<double>(resultScene.closest(dense.positions[i]).distance) * unit);
            advance(r.size());
        });
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rp.size(), 1024), [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i)
                res.resultError[i] = static_cast<float>(static_cast<double>(scene.closest(rp[i]).distance) * unit);
            advance(r.size());
        });
        auto stats = [](const std::vector<float>& e, double& rms, double& mx) {
            double s = 0.0;
            mx = 0.0;
            for (float x : e) {
                s += static_cast<double>(x) * static_cast<double>(x);
                mx = std::max(mx, static_cast<double>(x));
            }
            rms = e.empty() ? 0.0 : std::sqrt(s / static_cast<double>(e.size()));
        };
        stats(toResult, rep.rmsDenseToResult, rep.maxDenseToResult);
        stats(res.resultError, rep.rmsResultToDense, rep.maxResultToDense);
        stage("measurement");
        progress("measure", 1.0);
    }
    rep.peakRssMiB = peakRssMiB();
    return res;
}

/// The report as JSON (the keys `dispmap bake --report` writes; docs/bake.md lists them).
inline nlohmann::json bakeReportJson(const BakeReport& r) {
    nlohmann::json j;
    j["input"] = {{"file", r.input},
                  {"vertices", r.inputVertices},
                  {"triangles", r.inputTriangles},
                  {"degenerate_dropped", r.degenerateDropped},
                  {"vertices_merged", r.weldedVertices},
                  {"vertices_unused", r.unusedVertices},
                  {"diagonal", r.diagonal}};
    j["base"] = {{"icm_vertices", r.icmVertices},
                 {"icm_faces", r.icmFaces},
                 {"vertices", r.baseVertices},
                 {"faces", r.baseFaces},
                 {"density", r.density},
                 {"tile_samples", r.tileTexels}};
    j["rms_percent"] = {{"dense_to_result", r.rmsDenseToResult}, {"result_to_dense", r.rmsResultToDense}};
    j["max_percent"] = {{"dense_to_result", r.maxDenseToResult}, {"result_to_dense", r.maxResultToDense}};
    j["result_triangles"] = r.resultTriangles;
    j["measure_factor"] = r.measureFactor;
    j["compression_ratio"] = r.compressionRatio;
    j["bytes"] = {{"input", r.inputBytes},
                  {"paper_representation", r.paperBytes},
                  {"tile_file", r.tileFileBytes},
                  {"base_binary", r.baseBinaryBytes}};
    j["file_compression_ratio"] = r.fileCompressionRatio;
    j["samples"] = r.extract.samples;
    j["hits"] = r.extract.hits;
    j["misses"] = r.extract.misses;
    j["foldovers"] = r.extract.foldovers;
    j["max_abs_displacement"] = r.extract.maxAbs;
    nlohmann::json it = nlohmann::json::array();
    for (const FitIteration& f : r.fit.iterations)
        it.push_back({{"rms_percent", f.rmsPercent}, {"max_percent", f.maxPercent}, {"reverse_rms_percent", f.reverseRmsPercent}, {"seconds", f.seconds},
                       {"undone", f.undone}});
    j["fitting"] = {{"samples", r.fit.samples},
                    {"iterations", it},
                    {"result_rms_percent", r.fit.iterations.empty() ? 0.0 : r.fit.result().rmsPercent}};
    j["tile_fit"] = {{"sweeps", r.tiles.sweeps}, {"max_residual", r.tiles.maxResidual}};
    nlohmann::json st = nlohmann::json::object();
    double total = 0;
    for (const BakeStage& s : r.stages) {
        st[s.name] = s.seconds;
        total += s.seconds;
    }
    j["seconds"] = st;
    j["seconds_total"] = total;
    j["peak_rss_mib"] = r.peakRssMiB;
    j["threads"] = r.threads;
    return j;
}

} // namespace dispmap
