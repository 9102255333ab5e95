// `dispmap bench --only cages`: what each set-up stage costs as cages grow.
//
// Time is wall time with the default thread count (all cores). Memory is read from the process:
// "held" is what the stage's result keeps (the heap in use after it, less before it:
// mallinfo2), "peak" the most the process's resident set grew during the stage (freed memory
// handed back first with malloc_trim, then VmHWM reset through /proc/self/clear_refs and read
// after the stage; "n/a" where the kernel refuses the reset).
#include "cages_table.h"

#include <malloc.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <unistd.h>
#include <vector>

#include <opensubdiv/far/primvarRefiner.h>

#include "cores_table.h"
#include "text_format.h"
#include "dispmap/bake/dense_mesh.h"
#include "dispmap/bake/simplify.h"
#include "dispmap/surface/base_surface.h"
#include "dispmap/surface/builtin.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/tessellator.h"
#include "dispmap/surface/tile_builder.h"

namespace dispmap::figures {

ControlMesh denseCage(const std::string& path, const std::string& name) {
    const DenseMesh dense = readDenseMesh(path);
    MeshDescription d;
    d.name = name;
    d.positions.reserve(dense.positions.size());
    for (const glm::vec3& p : dense.positions) d.positions.emplace_back(p);
    d.faceSizes.assign(dense.triangles.size(), 3);
    d.faceVertices.reserve(3 * dense.triangles.size());
    for (const glm::uvec3& t : dense.triangles)
        for (int c = 0; c < 3; ++c) d.faceVertices.push_back(static_cast<int>(t[c]));
    return ControlMesh(std::move(d));
}

ControlMesh decimatedCage(const std::string& path, int faces, const std::string& label) {
    SimplifyOptions so;
    so.targetFaces = faces;
    MeshDescription d = simplifiedControlMesh(readDenseMesh(path), so, nullptr);
    d.name = label + " decimated to " + std::to_string(d.faceSizes.size()) + " triangles";
    return ControlMesh(std::move(d));
}

double cageDiagonal(const ControlMesh& mesh) {
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (const glm::dvec3& p : mesh.description().positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    return glm::length(hi - lo);
}

namespace {

constexpr double kMiB = 1048576.0;

double heapMiB() {
    const struct mallinfo2 m = mallinfo2();
    return static_cast<double>(m.uordblks + m.hblkhd) / kMiB;
}

double residentMiB() {
    std::ifstream f("/proc/self/statm");
    long pages = 0, resident = 0;
    f >> pages >> resident;
    return static_cast<double>(resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) / kMiB;
}

/// Resets the peak resident set to the present one; false where the kernel does not allow it.
bool resetPeak() {
    std::ofstream f("/proc/self/clear_refs");
    f << "5";
    f.flush();
    return static_cast<bool>(f);
}

double peakMiB() {
    std::ifstream f("/proc/self/status");
    std::string line;
    while (std::getline(f, line))
        if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
    return -1;
}

struct Usage {
    double seconds = 0, heldMiB = 0, peakMiB = -1;
};

Usage measured(const std::function<void()>& f) {
    malloc_trim(0); // hand freed memory back, so that the resident set starts from what is in use
    const bool peak = resetPeak();
    const double rss0 = residentMiB(), heap0 = heapMiB();
    Usage u;
    u.seconds = secondsOf(f);
    u.heldMiB = heapMiB() - heap0;
    if (peak) u.peakMiB = peakMiB() - rss0;
    return u;
}

/// The built-in torus cage of n x m quads (radii 2 and 0.6), or those quads split into two
/// triangles each.
ControlMesh torus(int n, int m, bool triangles) {
    const std::string name = "torus " + std::to_string(n) + "x" + std::to_string(m);
    ControlMesh quads = builtin::torusCage(n, m, 2.0, 0.6, name);
    if (!triangles) return quads;
    MeshDescription d = quads.description();
    d.name = name + " triangulated";
    const std::vector<int> q = d.faceVertices;
    d.faceSizes.assign(2 * q.size() / 4, 3);
    d.faceVertices.clear();
    for (std::size_t f = 0; f + 3 < q.size(); f += 4)
        d.faceVertices.insert(d.faceVertices.end(), {q[f], q[f + 1], q[f + 2], q[f], q[f + 2], q[f + 3]});
    return ControlMesh(std::move(d));
}

/// `mesh` refined uniformly `levels` times by Catmull-Clark (OpenSubdiv Far), as a new cage:
/// a dense quad cage whose extraordinary vertices are only those of the original (and its
/// N-gons' centres), as a production cage after retopology.
ControlMesh refinedCage(const ControlMesh& mesh, const std::string& name, int levels) {
    std::unique_ptr<Far::TopologyRefiner> refiner = mesh.createRefiner();
    refiner->RefineUniform(Far::TopologyRefiner::UniformOptions(levels));
    std::vector<detail::OsdPoint> points(static_cast<std::size_t>(refiner->GetNumVerticesTotal()));
    for (std::size_t i = 0; i < mesh.description().positions.size(); ++i) points[i].p = mesh.description().positions[i];
    Far::PrimvarRefinerReal<double> primvar(*refiner);
    detail::OsdPoint* src = points.data();
    for (int level = 1; level <= levels; ++level) {
        detail::OsdPoint* dst = src + refiner->GetLevel(level - 1).GetNumVertices();
        primvar.Interpolate(level, src, dst);
        src = dst;
    }
    const Far::TopologyLevel& last = refiner->GetLevel(levels);
    MeshDescription d;
    d.name = name + " refined " + std::to_string(levels) + "x";
    for (int v = 0; v < last.GetNumVertices(); ++v) d.positions.push_back(src[v].p);
    for (int f = 0; f < last.GetNumFaces(); ++f) {
        const Far::ConstIndexArray fv = last.GetFaceVertices(f);
        d.faceSizes.push_back(fv.size());
        for (int i = 0; i < fv.size(); ++i) d.faceVertices.push_back(fv[i]);
    }
    return ControlMesh(std::move(d));
}

struct CageRow {
    std::string cage, kind;
    int faces = 0, ptexFaces = 0, isolation = 0;
    Usage base, tiles, surface, tess;
    int triangles = 0;
};

/// The stages of a surface from a cage: base surface, tiles (2^3, a small procedural D), the
/// displaced surface, a tessellation at factor 2.
/// `keep`, if given, receives the base surface (the dense rows measure its accuracy after).
// gregory: OpenSubdiv's Gregory-basis end caps (the default), else B-spline-basis ones (the
// cage's name says so).
CageRow stages(const ControlMesh& mesh, const std::string& kind, int isolation, std::unique_ptr<BaseSurface>* keep = nullptr,
               bool gregory = true) {
    CageRow r;
    r.cage = mesh.description().name + (gregory ? "" : " (B-spline end caps)");
    r.kind = kind;
    r.faces = mesh.base().GetNumFaces();
    r.ptexFaces = mesh.ptexFaceCount();
    r.isolation = isolation;
    std::unique_ptr<BaseSurface> base;
    BaseSurfaceOptions bo;
    bo.isolationLevel = isolation;
    bo.gregoryEndCaps = gregory;
    r.base = measured([&] { base = std::make_unique<BaseSurface>(mesh, bo); });
    TileSet tiles;
    r.tiles = measured([&] {
        tiles = buildTiles(mesh, uniformTileSizes(mesh, 3),
                           FunctionSource([](int f, double u, double v) { return 0.01 * builtin::defaultDisplacement(f, u, v); }));
    });
    std::unique_ptr<DisplacedSurface> surface;
    r.surface = measured([&] { surface = std::make_unique<DisplacedSurface>(*base, tiles); });
    TriangleMesh m;
    r.tess = measured([&] { m = tessellate(*surface, uniformTessFactors(*base, 2.0)); });
    r.triangles = m.triangleCount();
    surface.reset();
    if (keep) *keep = std::move(base);
    return r;
}

std::string mib(double v) { return fixed(v, std::abs(v) < 10 ? 1 : 0); }
std::string peak(double v) { return v < 0 ? std::string("n/a") : mib(v); }

/// Least-squares slope of log y against log x over the points with y > 0 ("n/a" with fewer than
/// two: a held size of 0 or less, as under a sanitizer's allocator, has no logarithm).
std::string slope(const std::vector<double>& x, const std::vector<double>& y) {
    std::vector<double> lx, ly;
    for (std::size_t i = 0; i < x.size(); ++i)
        if (y[i] > 0) {
            lx.push_back(std::log(x[i]));
            ly.push_back(std::log(y[i]));
        }
    if (lx.size() < 2) return "n/a";
    double mx = 0, my = 0;
    for (std::size_t i = 0; i < lx.size(); ++i) {
        mx += lx[i];
        my += ly[i];
    }
    mx /= static_cast<double>(lx.size());
    my /= static_cast<double>(lx.size());
    double sxy = 0, sxx = 0;
    for (std::size_t i = 0; i < lx.size(); ++i) {
        sxy += (lx[i] - mx) * (ly[i] - my);
        sxx += (lx[i] - mx) * (lx[i] - mx);
    }
    return sxx > 0 ? fixed(sxy / sxx, 2) : std::string("n/a");
}

/// Points in the corner quarter of every Ptex corner at an extraordinary vertex (where the
/// isolation level matters; elsewhere every level gives the same B-spline patches), with the
/// surface's position and unit normal there.
struct Probes {
    std::vector<int> face;
    std::vector<glm::dvec2> uv;
    std::vector<glm::dvec3> p, n;
};

Probes probesOf(const BaseSurface& s) {
    Probes out;
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(0.0, 0.25);
    for (int f = 0; f < s.faceCount(); ++f)
        for (int c = 0; c < 4; ++c) {
            if (s.isHole(f) || !s.isExtraordinaryCorner(f, c)) continue;
            for (int i = 0; i < 2; ++i) {
                const double a = U(rng), b = U(rng);
                out.face.push_back(f);
                out.uv.emplace_back(c == 1 || c == 2 ? 1 - a : a, c >= 2 ? 1 - b : b);
            }
        }
    for (std::size_t i = 0; i < out.face.size(); ++i) {
        const BaseSample<double> b = s.evaluate<double>(out.face[i], out.uv[i].x, out.uv[i].y, false);
        out.p.push_back(b.p);
        out.n.push_back(glm::normalize(glm::cross(b.du, b.dv)));
    }
    return out;
}

struct Deviation {
    double maxP = 0, maxDeg = 0, rmsDeg = 0;
};

Deviation deviation(const BaseSurface& s, const Probes& ref, double diag) {
    Deviation d;
    double sum = 0;
    for (std::size_t i = 0; i < ref.face.size(); ++i) {
        const BaseSample<double> b = s.evaluate<double>(ref.face[i], ref.uv[i].x, ref.uv[i].y, false);
        d.maxP = std::max(d.maxP, glm::length(b.p - ref.p[i]) / diag);
        const double c = std::clamp(glm::dot(glm::normalize(glm::cross(b.du, b.dv)), ref.n[i]), -1.0, 1.0);
        const double deg = std::acos(c) * 57.29577951308232;
        d.maxDeg = std::max(d.maxDeg, deg);
        sum += deg * deg;
    }
    d.rmsDeg = ref.face.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(ref.face.size()));
    return d;
}

} // namespace

void printCagesTable(std::ostream& out, const CagesTableArgs& a) {
    std::unique_ptr<std::ofstream> csv;
    if (!a.csv.empty()) {
        csv = std::make_unique<std::ofstream>(a.csv);
        *csv << "cage,kind,faces,ptex_faces,isolation,stage,seconds,held_mib,peak_mib\n";
    }
    const bool peaks = resetPeak();
    out << "Production-size cages: each stage's wall time (all cores), the memory its result holds and the most the\n"
        << "process grew during it (peak" << (peaks ? "" : ": n/a, /proc/self/clear_refs refused") << "), MiB. Stages: "
        << "base surface (OpenSubdiv's adaptive refinement, patch table, points), tiles (2^3, a procedural D), the\n"
        << "displaced surface, a tessellation at factor 2.\n\n"
        << "| cage | faces | Ptex faces | isolation | base s | base held / peak | tiles s | tiles held / peak | surface s | tessellate s "
           "| triangles |\n|---|---|---|---|---|---|---|---|---|---|---|\n";
    std::vector<CageRow> rows;
    auto print = [&](const CageRow& r) {
        out << "| " << r.cage << " | " << r.faces << " | " << r.ptexFaces << " | " << r.isolation << " | " << fixed(r.base.seconds, 3)
            << " | " << mib(r.base.heldMiB) << " / " << peak(r.base.peakMiB) << " | " << fixed(r.tiles.seconds, 3) << " | "
            << mib(r.tiles.heldMiB) << " / " << peak(r.tiles.peakMiB) << " | " << fixed(r.surface.seconds, 3) << " | " << fixed(r.tess.seconds, 3) << " | " << r.triangles
            << " |\n";
        if (csv) {
            const std::pair<const char*, const Usage*> st[4] = {{"base", &r.base}, {"tiles", &r.tiles}, {"surface", &r.surface}, {"tessellate", &r.tess}};
            for (const auto& [name, u] : st)
                *csv << '"' << r.cage << "\"," << r.kind << "," << r.faces << "," << r.ptexFaces << "," << r.isolation << "," << name << ","
                     << u->seconds << "," << u->heldMiB << "," << u->peakMiB << "\n";
        }
        out.flush();
    };
    // Synthetic tori of about 1k, 10k, 100k faces: quads (valence 4 everywhere: no isolation
    // anywhere) and triangles (Catmull-Clark makes every vertex and face centre extraordinary:
    // isolation everywhere, the worst case). Triangles at isolation 6 stop at 10k faces: 100k
    // would hold about 3 GiB and peak near 11 GiB during the refinement (the fandisk and bunny
    // rows below scale so).
    const int sizes[3][2] = {{40, 25}, {125, 80}, {400, 250}};
    const int triSizes[3][2] = {{25, 20}, {100, 50}, {250, 200}};
    const int count = a.quick ? 2 : 3;
    for (int kind = 0; kind < 2; ++kind)
        for (int isolation : {2, 6})
            for (int s = 0; s < count; ++s) {
                if (a.quick && isolation == 6) continue;
                const bool tri = kind == 1;
                if (tri && isolation == 6 && s == 2) continue;
                const ControlMesh mesh = tri ? torus(triSizes[s][0], triSizes[s][1], true) : torus(sizes[s][0], sizes[s][1], false);
                rows.push_back(stages(mesh, tri ? "torus triangles" : "torus quads", isolation));
                print(rows.back());
            }
    // Quad-dominant production-size cages: Spot refined 4 and 5 times.
    if (!a.quick) {
        const ControlMesh spot = ControlMesh::fromObjFile(a.dataDir + "/spot_control_mesh.obj");
        for (int levels : {4, 5}) {
            const ControlMesh cage = refinedCage(spot, "Spot", levels);
            for (int isolation : {6, 2}) {
                rows.push_back(stages(cage, "quad cage", isolation));
                print(rows.back());
            }
        }
    }
    // Real dense triangle cages, each at isolation 6, 4 and 2, and at 2 with B-spline end caps.
    struct Dense {
        std::string file, name;
    };
    std::vector<std::pair<std::string, Deviation>> accuracy[2];
    const Dense dense[2] = {{"cgal_fandisk.off", "fandisk"}, {"cgal_bunny00.off", "bunny"}};
    for (int i = 0; i < 2 && !a.quick; ++i) {
        const std::string path = a.denseDir + "/" + dense[i].file;
        if (!std::filesystem::exists(path)) continue;
        const ControlMesh mesh = denseCage(path, dense[i].name);
        const double diag = cageDiagonal(mesh);
        Probes ref;
        // The default end caps at 6, 4 and 2, then the cheaper B-spline-basis end caps at 2.
        for (const auto& [isolation, gregory] : {std::pair{6, true}, std::pair{4, true}, std::pair{2, true}, std::pair{2, false}}) {
            std::unique_ptr<BaseSurface> s;
            rows.push_back(stages(mesh, "dense", isolation, &s, gregory));
            print(rows.back());
            if (isolation == 6)
                ref = probesOf(*s);
            else
                accuracy[i].emplace_back(std::to_string(isolation) + (gregory ? "" : ", B-spline end caps"), deviation(*s, ref, diag));
        }
        for (auto& [level, d] : accuracy[i])
            level = dense[i].name + " (" + std::to_string(ref.face.size()) + " points near extraordinary vertices), isolation " + level;
    }

    // The 52k-triangle cage (armadillo class): the bunny decimated to 52000 triangles
    // (meshoptimizer, as `dispmap bake` does), at isolation 2 with both kinds of end caps: its
    // whole set-up (base surface + tiles + displaced surface) and the memory it holds.
    std::vector<CageRow> target;
    if (!a.quick && std::filesystem::exists(a.denseDir + "/cgal_bunny00.off")) {
        const ControlMesh named = decimatedCage(a.denseDir + "/cgal_bunny00.off", 52000, "bunny");
        for (bool gregory : {true, false}) {
            rows.push_back(stages(named, "dense", 2, nullptr, gregory));
            print(rows.back());
            target.push_back(rows.back());
        }
    }

    // Growth exponents: slope of log(cost) against log(faces) over each series.
    out << "\nGrowth exponents (least-squares slope of log cost against log faces; 1 = linear):\n\n"
        << "| series | isolation | faces | base time | base held | tiles time | tiles held | tessellate time |\n|---|---|---|---|---|---|---|---|\n";
    for (const char* kind : {"torus quads", "torus triangles"})
        for (int isolation : {2, 6}) {
            std::vector<double> x, bt, bh, tt, th, te;
            int first = 0, last = 0;
            for (const CageRow& r : rows)
                if (r.kind == kind && r.isolation == isolation) {
                    x.push_back(r.faces);
                    bt.push_back(r.base.seconds);
                    bh.push_back(r.base.heldMiB);
                    tt.push_back(r.tiles.seconds);
                    th.push_back(r.tiles.heldMiB);
                    te.push_back(r.tess.seconds);
                    first = first == 0 ? r.faces : first;
                    last = r.faces;
                }
            if (x.size() < 2) continue;
            out << "| " << kind << " | " << isolation << " | " << first << " to " << last << " | " << slope(x, bt) << " | " << slope(x, bh)
                << " | " << slope(x, tt) << " | " << slope(x, th) << " | " << slope(x, te) << " |\n";
        }
    if (!target.empty()) {
        out << "\nThe 52k-triangle cage's whole set-up (base surface + tiles + displaced surface, all cores): time, the memory\n"
            << "the surface holds (base + tiles), and the most the process grew at any stage (the tiles' peak on top of the base\n"
            << "surface they are built beside):\n\n| cage | set-up s | held MiB | peak MiB |\n|---|---|---|---|\n";
        for (const CageRow& r : target) {
            const double held = r.base.heldMiB + r.tiles.heldMiB;
            const double top = r.base.peakMiB < 0 || r.tiles.peakMiB < 0 ? -1 : std::max(r.base.peakMiB, r.base.heldMiB + r.tiles.peakMiB);
            out << "| " << r.cage << ", isolation " << r.isolation << " | " << fixed(r.base.seconds + r.tiles.seconds + r.surface.seconds, 3)
                << " | " << mib(held) << " | " << peak(top) << " |\n";
        }
    }
    if (!accuracy[0].empty() || !accuracy[1].empty()) {
        out << "\nWhat a lower isolation gives up on the dense cages, against isolation 6 (the default), at two points in the\n"
            << "corner quarter of every Ptex corner at an extraordinary vertex: base-surface position (of the diagonal) and\n"
            << "normal:\n\n| cage, level | max position | max normal | RMS normal |\n|---|---|---|---|\n";
        for (const auto& list : accuracy)
            for (const auto& [name, d] : list)
                out << "| " << name << " | " << sci(d.maxP) << " | " << fixed(d.maxDeg, 2) << "° | " << fixed(d.rmsDeg, 3) << "° |\n";
    }
}

} // namespace dispmap::figures
