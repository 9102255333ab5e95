#include "figures.h"

#include <benchmark/benchmark.h>

#include "dispmap/surface/builtin.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/core/file_io.h"
#include "swimming.h"
#include "dispmap/surface/tessellator.h"

#include <chrono>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <map>
#include <random>
#include <sstream>
#include <memory>
#include <vector>

namespace dispmap::figures {


ControlMesh defaultMesh() { return builtin::defaultMesh(); }
double defaultDisplacement(int face, double u, double v) { return builtin::defaultDisplacement(face, u, v); }

void printTileStats(std::ostream& out, const std::string& label, const TileSet& tiles, const BuildReport* r) {
    std::map<int, int> bySize;
    std::size_t coeffs = 0;
    for (const Tile& t : tiles.tiles) {
        ++bySize[t.size()];
        coeffs += t.coefficients.size();
    }
    const PackedTiles p = tiles.pack();
    out << label << "\n  tiles: " << tiles.tileCount() << " (";
    bool first = true;
    for (auto [s, n] : bySize) {
        out << (first ? "" : ", ") << n << " x " << s << "^2";
        first = false;
    }
    out << "), mip filter " << toString(tiles.filter) << "\n  coefficients (all levels, overlap included): " << coeffs
        << "\n  packed texture: " << p.width << " x " << p.height << " texels, " << p.usedTexels
        << " in tile footprints (paper's (1.5s+4)(s+2) per tile: " << p.paperTexels << "), "
        << std::fixed << std::setprecision(1) << 100.0 * double(p.usedTexels) / double(p.width * p.height)
        << " % used, " << double(p.texels.size() * 4 + p.records.size() * 16) / 1024.0 << " KiB as float32 + records\n";
    if (r)
        out << std::scientific << std::setprecision(2) << "  fit: " << r->sweeps << " sweeps, last change "
            << r->lastChange << ", max interpolation residual " << r->maxResidual << " (away from constrained corners "
            << r->maxResidualAwayFromConstraints << ")\n  constrained (extraordinary) vertices: "
            << r->constrainedVertices << ", quad/sub-face T-junctions: " << r->tJunctions << "\n";
    out << std::defaultfloat;
}

namespace {
// A torus of quads carrying a band-limited random displacement: the reference for the mip
// table (no constrained corners, so the levels differ only by the filter).
struct MipScene {
    ControlMesh mesh;
    std::vector<int> k;
    DisplacementFunction source;
};
MipScene mipScene(bool smooth) {
    const int n = 6, m = 4;
    ControlMesh mesh = builtin::torusCage(n, m, 2.0, 1.0, "mip torus");
    std::vector<int> k = uniformTileSizes(mesh, 6);
    // Periodic over the torus: frequencies in cycles per face, 1..24 (the finest level has 64
    // texels per face, so content up to its Nyquist limit of 32).
    auto source = [n, m, smooth](int face, double u, double v) {
        const double x = (face % n + u) / n, y = (face / n + v) / m, tau = 6.283185307179586;
        double d = 0;
        const int fx[] = {1, 2, 4, 8, 16, 24}, fy[] = {1, 3, 4, 6, 12, 20};
        for (int i = 0; i < (smooth ? 2 : 6); ++i)
            d += std::sin(tau * (fx[i] * n * x + 0.3 * i)) * std::cos(tau * (fy[i] * m * y)) / (1 + i);
        return d;
    };
    return {std::move(mesh), std::move(k), source};
}
} // namespace

void printMipTable(std::ostream& out, const std::string& csvPath) {
    CsvOut csv(csvPath, "data,filter,level,size,rel_rms_error,rel_max_error,build_ms");
    out << "Mip pyramids, Haar vs quadratic B-wavelet (torus of 24 tiles, 64^2 each):\n"
        << "  error of level m against the finest level (relative to its RMS), 128^2 samples per tile;\n"
        << "  build = fit + all mips of the whole set, best of 3 (ms)\n"
        << "  data    filter    build ms  level  size   rel RMS err   rel max err\n";
    for (bool smooth : {true, false}) {
        MipScene sc = mipScene(smooth);
        const char* data = smooth ? "smooth" : "rough";
        for (MipFilter f : {MipFilter::Haar, MipFilter::BWavelet}) {
            BuildOptions o;
            o.filter = f;
            double best = 1e300;
            TileSet ts;
            for (int rep = 0; rep < 3; ++rep) {
                auto t0 = std::chrono::steady_clock::now();
                ts = buildTiles(sc.mesh, sc.k, sc.source, o);
                best = std::min(best, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
            }
            const int levels = ts.tiles[0].k;
            const int N = 128; // samples per face side
            double refRms = 0;
            for (std::size_t t = 0; t < ts.tiles.size(); ++t)
                for (int j = 0; j < N; ++j)
                    for (int i = 0; i < N; ++i) {
                        const double d = ts.evaluate(int(t), 0, glm::dvec2((i + 0.5) / N, (j + 0.5) / N));
                        refRms += d * d;
                    }
            refRms = std::sqrt(refRms / double(ts.tiles.size() * N * N));
            for (int m = 1; m < levels; ++m) {
                double se = 0, mx = 0;
                for (std::size_t t = 0; t < ts.tiles.size(); ++t)
                    for (int j = 0; j < N; ++j)
                        for (int i = 0; i < N; ++i) {
                            const glm::dvec2 p((i + 0.5) / N, (j + 0.5) / N);
                            const double e = ts.evaluate(int(t), m, p) - ts.evaluate(int(t), 0, p);
                            se += e * e;
                            mx = std::max(mx, std::abs(e));
                        }
                const double rms = std::sqrt(se / double(ts.tiles.size() * N * N)) / refRms;
                out << "  " << std::left << std::setw(8) << data << std::setw(9) << toString(f) << std::right;
                if (m == 1)
                    out << std::fixed << std::setprecision(1) << std::setw(9) << best;
                else
                    out << std::setw(9) << "";
                out << std::setw(7) << m << std::setw(6) << (64 >> m) << std::scientific << std::setprecision(3)
                    << std::setw(14) << rms << std::setw(14) << mx / refRms << std::defaultfloat << "\n";
                if (csv)
                    csv << data << "," << toString(f) << "," << m << "," << (64 >> m) << "," << rms << "," << mx / refRms
                        << "," << best << "\n";
            }
        }
    }
    csv.commit();
}

// ---- What accurate normals cost: base surface vs displaced, approximate / accurate / auto ----
namespace {
using builtin::torusMesh;
using builtin::torusDisplacement;

double angleBetween(glm::dvec3 a, glm::dvec3 b) {
    // atan2 of |a x b| and a . b: accurate for small angles too.
    return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
}

struct NormalRow {
    std::string scene, precision, variant;
    double ns = 0, ratio = 1, meanDeg = 0, maxDeg = 0;
};

// One variant of the table: the base surface alone (ds == nullptr), or a displaced surface
// evaluated in a mode.
struct NormalVariant {
    std::string name;
    const DisplacedSurface* ds;
    NormalMode mode;
    int ratioTo; ///< index of the variant this one's time is divided by
};

template <typename real>
void timeNormals(const std::string& sceneName, const BaseSurface& base, const DisplacedSurface& reference,
                 const std::vector<NormalVariant>& variants, const std::vector<int>& faces,
                 const std::vector<glm::dvec2>& uv, std::vector<NormalRow>& rows) {
    const std::size_t n = uv.size();
    std::vector<glm::dvec3> ref(n);
    for (std::size_t i = 0; i < n; ++i)
        ref[i] = reference.evaluate<double>(faces[i], uv[i].x, uv[i].y, NormalMode::Accurate).normal;
    std::vector<glm::vec<2, real>> p(n);
    for (std::size_t i = 0; i < n; ++i) p[i] = glm::vec<2, real>(uv[i]);
    std::vector<glm::vec<3, real>> nrm(n), pos(n);
    auto run = [&](const NormalVariant& v) {
        const auto t0 = std::chrono::steady_clock::now();
        for (std::size_t i = 0; i < n; ++i) {
            if (!v.ds) {
                const BaseSample<real> s = base.evaluate<real>(faces[i], p[i].x, p[i].y, false);
                const glm::vec<3, real> z(0);
                nrm[i] = kern::dmBaseNormal(s.du, s.dv, z, z, z, p[i], glm::vec<3, real>(0, 0, 1));
                pos[i] = s.p;
            } else {
                const SurfaceSample<real> r = v.ds->evaluate<real>(faces[i], p[i].x, p[i].y, v.mode);
                nrm[i] = r.normal;
                pos[i] = r.position;
            }
        }
        benchmark::DoNotOptimize(nrm.data());
        benchmark::DoNotOptimize(pos.data());
        return std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count() / double(n);
    };
    std::vector<double> best(variants.size(), 1e300);
    for (int round = 0; round < 15; ++round) // interleaved, best of 15: the machine is shared
        for (std::size_t v = 0; v < variants.size(); ++v) best[v] = std::min(best[v], run(variants[v]));
    for (std::size_t v = 0; v < variants.size(); ++v) {
        run(variants[v]);
        NormalRow r{sceneName, sizeof(real) == 4 ? "float" : "double", variants[v].name, best[v],
                    best[v] / best[static_cast<std::size_t>(variants[v].ratioTo)], 0, 0};
        for (std::size_t i = 0; i < n; ++i) {
            const double a = angleBetween(glm::dvec3(nrm[i]), ref[i]) * 57.29577951308232;
            r.meanDeg += a / double(n);
            r.maxDeg = std::max(r.maxDeg, a);
        }
        rows.push_back(r);
    }
}
} // namespace

void printNormalTable(std::ostream& out, const std::string& csvPath) {
    CsvOut csv(csvPath, "scene,precision,variant,ns_per_eval,ratio,mean_error_deg,max_error_deg");
    struct Scene {
        std::string name;
        ControlMesh mesh;
        DisplacementFunction d;
    };
    std::vector<Scene> scenes;
    scenes.push_back({"box cage (valence 3, 5, a pentagon, a triangle), |D| <= 0.07, size 2", defaultMesh(), defaultDisplacement});
    scenes.push_back({"torus 8 x 6 (radii 2, 0.6), |D| <= 0.12 on one side, ~0 on the other", torusMesh(), torusDisplacement});
    const double tolerances[2] = {2.0, 6.0}; // degrees, auto mode
    out << "Normals: what accuracy costs (CPU, one thread, k = 5 tiles; ns per evaluation of position and normal,\n"
        << "  best of 15 interleaved rounds over 4096 random (face, u, v); error: angle to the double-precision\n"
        << "  accurate normal (the base row: the error of not displacing at all); ratio: approximate / base,\n"
        << "  accurate and auto / approximate)\n";
    std::vector<NormalRow> rows;
    for (const Scene& sc : scenes) {
        const BaseSurface base(sc.mesh);
        const TileSet ts = buildTiles(sc.mesh, uniformTileSizes(sc.mesh, 5), sc.d);
        std::vector<std::unique_ptr<DisplacedSurface>> surfaces;
        for (double tol : tolerances) {
            DisplacedSurfaceOptions o;
            o.autoTolerance = tol / 57.29577951308232;
            surfaces.push_back(std::make_unique<DisplacedSurface>(base, ts, o));
        }
        const DisplacedSurface& ds = *surfaces[0];
        std::vector<NormalVariant> variants = {{"base surface (s, N_s)", nullptr, NormalMode::Approximate, 0},
                                               {"displaced, approximate", &ds, NormalMode::Approximate, 0},
                                               {"displaced, accurate", &ds, NormalMode::Accurate, 1}};
        for (std::size_t t = 0; t < surfaces.size(); ++t) {
            std::ostringstream name;
            name << "displaced, auto " << tolerances[t] << " deg";
            variants.push_back({name.str(), surfaces[t].get(), NormalMode::Auto, 1});
        }
        std::mt19937 rng(7);
        std::uniform_real_distribution<double> U(0, 1);
        std::vector<int> faces;
        std::vector<glm::dvec2> uv;
        for (int i = 0; i < 4096; ++i) {
            int f;
            do f = int(rng() % unsigned(base.faceCount()));
            while (base.isHole(f));
            faces.push_back(f);
            uv.emplace_back(U(rng), U(rng));
        }
        const std::size_t first = rows.size();
        timeNormals<float>(sc.name, base, ds, variants, faces, uv, rows);
        timeNormals<double>(sc.name, base, ds, variants, faces, uv, rows);
        out << "  " << sc.name << ": " << base.faceCount() << " faces; auto evaluates";
        for (std::size_t t = 0; t < surfaces.size(); ++t)
            out << (t ? "," : "") << " " << surfaces[t]->autoAccurateCount() << " accurately at " << tolerances[t] << " deg";
        out << "\n";
        for (std::size_t i = first; i < rows.size(); ++i) {
            const NormalRow& r = rows[i];
            out << "    " << std::left << std::setw(7) << r.precision << std::setw(24) << r.variant << std::right
                << std::fixed << std::setprecision(1) << std::setw(8) << r.ns << " ns" << std::setprecision(2)
                << std::setw(7) << r.ratio << "x" << std::scientific << std::setprecision(2) << "   error mean "
                << r.meanDeg << " deg, max " << r.maxDeg << " deg\n"
                << std::defaultfloat;
            if (csv)
                csv << '"' << r.scene << "\"," << r.precision << ",\"" << r.variant << "\"," << r.ns << "," << r.ratio << ","
                    << r.meanDeg << "," << r.maxDeg << "\n";
        }
    }
    csv.commit();
}

// ---- The isolation level: base-surface error near extraordinary vertices vs cost ----
void printIsolationTable(std::ostream& out, const std::string& csvPath) {
    CsvOut csv(csvPath, "isolation,patches,build_ms,ns_per_eval,max_position_error,max_normal_error_deg");
    const ControlMesh mesh = defaultMesh();
    BaseSurfaceOptions refOptions;
    refOptions.isolationLevel = 10;
    const BaseSurface ref(mesh, refOptions);
    // Points in the corner quarter of every face that touches an extraordinary corner: where
    // the end caps are (elsewhere every level gives the same B-spline patches).
    std::vector<int> faces;
    std::vector<glm::dvec2> uv;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> U(0, 0.25);
    for (int f = 0; f < ref.faceCount(); ++f)
        for (int c = 0; c < 4; ++c) {
            if (!ref.isExtraordinaryCorner(f, c)) continue;
            for (int i = 0; i < 256; ++i) {
                const double a = U(rng), b = U(rng);
                faces.push_back(f);
                uv.emplace_back(c == 1 || c == 2 ? 1 - a : a, c >= 2 ? 1 - b : b);
            }
        }
    std::vector<glm::dvec3> refP(faces.size()), refN(faces.size());
    for (std::size_t i = 0; i < faces.size(); ++i) {
        const BaseSample<double> s = ref.evaluate<double>(faces[i], uv[i].x, uv[i].y, false);
        refP[i] = s.p;
        refN[i] = glm::normalize(glm::cross(s.du, s.dv));
    }
    out << "Isolation level (OpenSubdiv adaptive refinement; Gregory end caps below it): the base surface near\n"
        << "  extraordinary vertices (default box cage, " << faces.size()
        << " points in the corner quarters of faces at valence-3/5 and N-gon centres) against level 10;\n"
        << "  position error relative to the cage size (2); build = refine + patch table + points, best of 3;\n"
        << "  eval = s, s_u, s_v in double, best of 9\n"
        << "  level  patches  build ms   ns/eval   max position err   max normal err (deg)\n";
    for (int level = 1; level <= 8; ++level) {
        BaseSurfaceOptions o;
        o.isolationLevel = level;
        double buildMs = 1e300;
        std::unique_ptr<BaseSurface> bs;
        for (int rep = 0; rep < 3; ++rep) {
            const auto t0 = std::chrono::steady_clock::now();
            bs = std::make_unique<BaseSurface>(mesh, o);
            buildMs = std::min(buildMs, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        }
        double ns = 1e300, maxP = 0, maxN = 0;
        std::vector<glm::dvec3> P(faces.size()), N(faces.size());
        for (int rep = 0; rep < 9; ++rep) {
            const auto t0 = std::chrono::steady_clock::now();
            for (std::size_t i = 0; i < faces.size(); ++i) {
                const BaseSample<double> s = bs->evaluate<double>(faces[i], uv[i].x, uv[i].y, false);
                P[i] = s.p;
                N[i] = glm::cross(s.du, s.dv);
            }
            benchmark::DoNotOptimize(P.data());
            ns = std::min(ns, std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count() /
                                  double(faces.size()));
        }
        for (std::size_t i = 0; i < faces.size(); ++i) {
            maxP = std::max(maxP, glm::length(P[i] - refP[i]) / 2.0);
            maxN = std::max(maxN, angleBetween(N[i], refN[i]) * 57.29577951308232);
        }
        const Far::PatchTable& t = bs->patchTable();
        int patches = 0;
        for (int a = 0; a < t.GetNumPatchArrays(); ++a) patches += t.GetNumPatches(a);
        out << std::setw(7) << level << std::setw(9) << patches << std::fixed << std::setprecision(2) << std::setw(10)
            << buildMs << std::setprecision(1) << std::setw(10) << ns << std::scientific << std::setprecision(2)
            << std::setw(19) << maxP << std::setw(23) << maxN << std::defaultfloat << "\n";
        if (csv) csv << level << "," << patches << "," << buildMs << "," << ns << "," << maxP << "," << maxN << "\n";
    }
    csv.commit();
}

// ---- The tessellation factor: distance to the surface vs triangles and time ----
void printTessellationTable(std::ostream& out, const std::string& csvPath) {
    CsvOut csv(csvPath, "factor,mips,triangles,ms,rms_distance,max_distance");
    const ControlMesh mesh = defaultMesh();
    const BaseSurface base(mesh);
    const TileSet ts = buildTiles(mesh, uniformTileSizes(mesh, 5), defaultDisplacement);
    const DisplacedSurface ds(base, ts);
    // The true surface f (finest D) at fixed points, against the piecewise-linear tessellation.
    const SurfaceProbe probe = probeSurface(ds, 4096, 5);
    out << "Tessellation factor (default scene, k = 5, integer spacing, approximate normals): distance from the\n"
        << "  tessellation to the displaced surface f (finest level) at 4096 random points, relative to the cage\n"
        << "  size (2); with mips the target is the mip-filtered surface, so the distance to f stays larger;\n"
        << "  ms: tessellate() on one thread, best of 5\n"
        << "  factor  mips   triangles        ms   RMS distance   max distance\n";
    for (MipSelection mips : {MipSelection::Off, MipSelection::TessFactor})
        for (double T : {2.0, 4.0, 8.0, 16.0, 32.0, 64.0}) {
            TessellateOptions o;
            o.spacing = Spacing::Integer;
            o.mips = mips;
            const Tessellator tess(ds, uniformTessFactors(base, T), o);
            double ms = 1e300;
            TriangleMesh m;
            for (int rep = 0; rep < 5; ++rep) {
                const auto t0 = std::chrono::steady_clock::now();
                m = tess.tessellate();
                ms = std::min(ms, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
            }
            const TriangleLocator loc(m, base.faceCount());
            double se = 0, mx = 0;
            for (std::size_t i = 0; i < probe.faces.size(); ++i) {
                const double d = glm::length(loc.position(probe.faces[i], probe.uvs[i]) - probe.truth[i]) / 2.0;
                se += d * d;
                mx = std::max(mx, d);
            }
            const double rms = std::sqrt(se / double(probe.faces.size()));
            const char* mipName = mips == MipSelection::Off ? "off" : "tf";
            out << std::setw(8) << T << std::setw(6) << mipName << std::setw(12) << m.triangleCount() << std::fixed
                << std::setprecision(2) << std::setw(10) << ms << std::scientific << std::setprecision(2) << std::setw(15)
                << rms << std::setw(15) << mx << std::defaultfloat << "\n";
            if (csv) csv << T << "," << mipName << "," << m.triangleCount() << "," << ms << "," << rms << "," << mx << "\n";
        }
    csv.commit();
}

// ---- Edits: re-fitting one face against rebuilding the whole tile set ----
void printEditTable(std::ostream& out, const std::string& csvPath) {
    CsvOut csv(csvPath, "mesh,k,tiles,rewritten,full_ms,refit_ms,max_difference");
    out << "Edits (paper §5): a bump (height 0.05) painted on one face; TileFitter::refit re-solves that tile and\n"
        << "  its neighbours with the rest fixed and rewrites only the tiles that changed, against buildTiles of the\n"
        << "  edited source; difference: max |D| between the two over 9 points per tile (the coupling the fixed\n"
        << "  tiles cut); ms best of 3, one thread\n"
        << "  mesh           k   tiles  rewritten   full ms   refit ms   ratio   max difference\n";
    for (const char* meshName : {"box", "torus"})
        for (int k : {4, 6}) {
            const ControlMesh mesh = builtin::builtinMesh(meshName);
            const std::vector<int> ks = uniformTileSizes(mesh, k);
            const auto bumped = [](int face, double u, double v) {
                const double r2 = (u - 0.5) * (u - 0.5) + (v - 0.5) * (v - 0.5);
                return defaultDisplacement(face, u, v) + (face == 1 ? 0.05 * std::exp(-20.0 * r2) : 0.0);
            };
            double fullMs = 1e300, refitMs = 1e300;
            TileSet full;
            std::vector<int> changed;
            double diff = 0;
            for (int rep = 0; rep < 3; ++rep) {
                auto t0 = std::chrono::steady_clock::now();
                full = buildTiles(mesh, ks, bumped);
                fullMs = std::min(fullMs, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
                TileFitter fitter(mesh, ks, defaultDisplacement);
                t0 = std::chrono::steady_clock::now();
                changed = fitter.refit({1}, bumped);
                refitMs = std::min(refitMs, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
                diff = 0;
                for (int t = 0; t < full.tileCount(); ++t)
                    for (double u : {0.1, 0.5, 0.9})
                        for (double v : {0.1, 0.5, 0.9})
                            diff = std::max(diff, std::abs(fitter.tiles().evaluateD1(t, 0, glm::dvec2(u, v)).x -
                                                           full.evaluateD1(t, 0, glm::dvec2(u, v)).x));
            }
            out << "  " << std::left << std::setw(13) << meshName << std::right << std::setw(3) << k << std::setw(8)
                << full.tileCount() << std::setw(11) << changed.size() << std::fixed << std::setprecision(2) << std::setw(10)
                << fullMs << std::setw(11) << refitMs << std::setw(7) << std::setprecision(1) << fullMs / refitMs << "x"
                << std::scientific << std::setprecision(2) << std::setw(17) << diff << std::defaultfloat << "\n";
            if (csv) csv << meshName << "," << k << "," << full.tileCount() << "," << changed.size() << "," << fullMs << ","
                         << refitMs << "," << diff << "\n";
        }
    csv.commit();
}

// ---- Google Benchmark timings ----
namespace {
template <typename real> void BM_Biquadratic(benchmark::State& state) {
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> U(0, 1);
    std::vector<glm::mat<3, 3, real>> c(1024);
    std::vector<glm::vec<2, real>> t(1024);
    for (std::size_t i = 0; i < c.size(); ++i) {
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) c[i][a][b] = static_cast<real>(U(rng));
        t[i] = glm::vec<2, real>(static_cast<real>(U(rng)), static_cast<real>(U(rng)));
    }
    std::size_t i = 0;
    const bool derivs = state.range(0) != 0;
    for (auto _ : state) {
        if (derivs)
            benchmark::DoNotOptimize(kern::dmBiquadraticD1(c[i & 1023], t[i & 1023]));
        else
            benchmark::DoNotOptimize(kern::dmBiquadratic(c[i & 1023], t[i & 1023]));
        ++i;
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}
BENCHMARK(BM_Biquadratic<float>)->Arg(0)->Arg(1)->ArgName("derivs");
BENCHMARK(BM_Biquadratic<double>)->Arg(0)->Arg(1)->ArgName("derivs");

// Whole evaluation from a TileSet: locate the sub-patch, gather 9 coefficients, evaluate.
template <typename real> void BM_TileEvaluate(benchmark::State& state) {
    static const TileSet ts = buildTiles(defaultMesh(), uniformTileSizes(defaultMesh(), 5), defaultDisplacement);
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> U(0, 1);
    std::vector<glm::vec<2, real>> p(1024);
    for (auto& x : p) x = glm::vec<2, real>(static_cast<real>(U(rng)), static_cast<real>(U(rng)));
    std::size_t i = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(ts.evaluateD1(int(i % std::size_t(ts.tileCount())), 0, p[i & 1023]));
        ++i;
    }
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}
BENCHMARK(BM_TileEvaluate<float>);
BENCHMARK(BM_TileEvaluate<double>);

// Fit + mips for the default mesh on one thread: throughput in samples (texels of the finest
// levels) per core (bench --only cores has the all-cores figures).
void BM_BuildTiles(benchmark::State& state) {
    const ControlMesh mesh = defaultMesh();
    const std::vector<int> k = uniformTileSizes(mesh, static_cast<int>(state.range(0)));
    BuildOptions o;
    o.threads = 1;
    o.filter = state.range(1) ? MipFilter::BWavelet : MipFilter::Haar;
    std::int64_t samples = 0;
    for (int kk : k) samples += std::int64_t(1) << (2 * kk);
    for (auto _ : state) benchmark::DoNotOptimize(buildTiles(mesh, k, defaultDisplacement, o));
    state.SetItemsProcessed(state.iterations() * samples);
}
BENCHMARK(BM_BuildTiles)->ArgsProduct({{4, 6}, {0, 1}})->ArgNames({"k", "bwavelet"})->Unit(benchmark::kMillisecond);

void BM_Pack(benchmark::State& state) {
    static const TileSet ts = buildTiles(defaultMesh(), uniformTileSizes(defaultMesh(), 6), defaultDisplacement);
    for (auto _ : state) benchmark::DoNotOptimize(ts.pack());
}
BENCHMARK(BM_Pack)->Unit(benchmark::kMillisecond);
} // namespace

int runBenchmarks(const std::vector<std::string>& flags) {
    std::vector<std::string> args = {"dispmap"};
    args.insert(args.end(), flags.begin(), flags.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    int argc = static_cast<int>(argv.size());
    benchmark::Initialize(&argc, argv.data());
    if (benchmark::ReportUnrecognizedArguments(argc, argv.data())) return 2;
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}

} // namespace dispmap::figures
