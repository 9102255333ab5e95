// The CPU reference tessellator: watertight on every test mesh (both spacings, uniform and
// distance factors, mixed tile sizes, mips on and off), shared vertices agree with both faces,
// fractional spacing is continuous in T, mips reduce swimming, the writers round-trip, and bad
// inputs are rejected with a message.
#include <catch2/catch.hpp>

#include <algorithm>
#include <bit>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <sstream>

#include "swimming.h"
#include "dispmap/io/mesh_writers.h"
#include "dispmap/surface/tessellator.h"
#include "test_files.h"
#include "test_support.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_tessellate {

using namespace dispmap;

namespace {

struct Scene {
    ControlMesh mesh;
    BaseSurface base;
    TileSet tiles;
    DisplacedSurface surface;
    double size; ///< of a face: the mean control edge
    Scene(ControlMesh m, const std::vector<int>& k, const DisplacementFunction& d, double scale)
        : mesh(std::move(m)), base(mesh), tiles(buildTiles(mesh, k, d)), surface(base, tiles), size(scale) {}
    /// Distance factors from about 1.5 near the eye to 6 far from it.
    TessFactors distanceFactors(glm::dvec3 direction) const {
        glm::dvec3 lo(1e300), hi(-1e300);
        for (const glm::dvec3& p : mesh.description().positions) {
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
        const double extent = glm::length(hi - lo);
        return distanceTessFactors(base, 0.5 * (lo + hi) + 0.8 * extent * glm::normalize(direction), 2.0 * extent);
    }
};

// The mean length of the control mesh's edges: the scale of a face.
double meanEdge(const ControlMesh& m) {
    const Far::TopologyLevel& L = m.base();
    const auto& p = m.description().positions;
    double sum = 0;
    for (int e = 0; e < L.GetNumEdges(); ++e) {
        auto ev = L.GetEdgeVertices(e);
        sum += glm::length(p[static_cast<std::size_t>(ev[0])] - p[static_cast<std::size_t>(ev[1])]);
    }
    return sum / L.GetNumEdges();
}

// Bumps of 5 % of a face's size, discontinuous between faces (the tiles make D C1 anyway).
DisplacementFunction bumps(double size) {
    return [a = 0.05 * size](int f, double u, double v) {
        return a * (std::sin(7.0 * u + 1.3 * f) * std::cos(5.0 * v - 0.7 * f) + 0.3 * std::cos(37.0 * (u + v)));
    };
}

// Sizes mixed per face (2..4) where the builder allows it: faces touching a non-quad get at
// least 3, quads sharing an edge with a non-quad exactly 3, non-quads 3 (sub-faces 2).
std::vector<int> randomTileSizes(const ControlMesh& mesh, unsigned seed) {
    const Far::TopologyLevel& L = mesh.base();
    const int nf = L.GetNumFaces();
    std::mt19937 rng(seed);
    std::vector<int> kf(static_cast<std::size_t>(nf));
    for (int& k : kf) k = 2 + static_cast<int>(rng() % 3);
    std::vector<char> ngonVertex(static_cast<std::size_t>(L.GetNumVertices()), 0);
    std::vector<char> ngonEdge(static_cast<std::size_t>(L.GetNumEdges()), 0);
    for (int f = 0; f < nf; ++f)
        if (L.GetFaceVertices(f).size() != 4) {
            for (int v : L.GetFaceVertices(f)) ngonVertex[static_cast<std::size_t>(v)] = 1;
            for (int e : L.GetFaceEdges(f)) ngonEdge[static_cast<std::size_t>(e)] = 1;
        }
    for (int f = 0; f < nf; ++f) {
        int& k = kf[static_cast<std::size_t>(f)];
        if (L.GetFaceVertices(f).size() != 4) {
            k = 3;
            continue;
        }
        for (int v : L.GetFaceVertices(f))
            if (ngonVertex[static_cast<std::size_t>(v)]) k = std::max(k, 3);
        for (int e : L.GetFaceEdges(f))
            if (ngonEdge[static_cast<std::size_t>(e)]) k = 3;
    }
    std::vector<int> k(static_cast<std::size_t>(mesh.ptexFaceCount()));
    for (int f = 0; f < nf; ++f) {
        const int first = mesh.ptex().GetFaceId(f), n = L.GetFaceVertices(f).size();
        if (n == 4)
            k[static_cast<std::size_t>(first)] = kf[static_cast<std::size_t>(f)];
        else
            for (int i = 0; i < n; ++i) k[static_cast<std::size_t>(first + i)] = kf[static_cast<std::size_t>(f)] - 1;
    }
    return k;
}

std::unique_ptr<Scene> makeScene(const std::string& name, bool mixed = false) {
    ControlMesh mesh = dmtest::shape(name);
    const double size = meanEdge(mesh);
    const std::vector<int> k = mixed ? randomTileSizes(mesh, 11) : uniformTileSizes(mesh, 3);
    return std::make_unique<Scene>(std::move(mesh), k, bumps(size), size);
}

// The tile edge e that (u, v) lies on and its edge parameter, for each edge that holds it.
std::vector<std::pair<int, double>> edgesAt(glm::dvec2 uv) {
    std::vector<std::pair<int, double>> out;
    if (uv.y == 0.0) out.emplace_back(0, uv.x);
    if (uv.x == 1.0) out.emplace_back(1, uv.y);
    if (uv.y == 1.0) out.emplace_back(2, 1.0 - uv.x);
    if (uv.x == 0.0) out.emplace_back(3, 1.0 - uv.y);
    return out;
}

// Every (tile, uv) that denotes the same surface point as (t, uv): closure over the edge links.
std::vector<std::pair<int, glm::dvec2>> samePoint(const TileTopology& topo, int t, glm::dvec2 uv) {
    std::vector<std::pair<int, glm::dvec2>> reps{{t, uv}};
    for (std::size_t i = 0; i < reps.size(); ++i) {
        const auto [rt, ruv] = reps[i];
        for (const auto& [e, y] : edgesAt(ruv))
            for (const TileTopology::Link& l : topo.links(rt, e)) {
                if (y < l.y0 - 1e-12 || y > l.y1 + 1e-12) continue;
                const double z = std::clamp(l.alpha - l.beta * y, 0.0, 1.0);
                glm::dvec2 q = dmtest::edgePoint(l.edge, z);
                q = glm::clamp(q, 0.0, 1.0);
                bool seen = false;
                for (const auto& [st, suv] : reps) seen = seen || (st == l.tile && glm::length(suv - q) < 1e-9);
                if (!seen) reps.emplace_back(l.tile, q);
            }
    }
    return reps;
}

struct WatertightReport {
    int badIndex = 0, degenerate = 0, unreferenced = 0, sameDirection = 0, crackEdges = 0, boundaryEdges = 0;
    int nonFinite = 0, clockwise = 0, againstNormal = 0;
    double signedVolume = 0;
};

// Directed-edge bookkeeping of a triangle mesh: every edge shared by exactly two triangles in
// opposite directions, a one-sided edge only on a tile edge at a mesh boundary or a hole.
WatertightReport watertight(const TriangleMesh& m, const Scene& sc) {
    const TileTopology& topo = sc.base.topology();
    WatertightReport r;
    std::vector<char> used(m.positions.size(), 0);
    std::map<std::pair<int, int>, int> directed; // (a, b) -> triangle
    for (int j = 0; j < m.triangleCount(); ++j) {
        const glm::ivec3 t = m.triangles[static_cast<std::size_t>(j)];
        bool ok = true;
        for (int i = 0; i < 3; ++i) ok = ok && t[i] >= 0 && t[i] < m.vertexCount();
        if (!ok) {
            ++r.badIndex;
            continue;
        }
        if (t.x == t.y || t.y == t.z || t.x == t.z) ++r.degenerate;
        for (int i = 0; i < 3; ++i) {
            used[static_cast<std::size_t>(t[i])] = 1;
            if (!directed.emplace(std::make_pair(t[i], t[(i + 1) % 3]), j).second) ++r.sameDirection;
        }
        const auto& uv = m.triangleUVs[static_cast<std::size_t>(j)];
        const glm::dvec2 a = uv[1] - uv[0], b = uv[2] - uv[0];
        if (!(a.x * b.y - a.y * b.x > 0.0)) ++r.clockwise;
        const glm::dvec3 p0 = m.positions[static_cast<std::size_t>(t.x)], p1 = m.positions[static_cast<std::size_t>(t.y)],
                         p2 = m.positions[static_cast<std::size_t>(t.z)];
        // Facing: against the base surface's normal at the triangle's centre (the vertex
        // normals of an unfiltered D alias at coarse factors and need not agree).
        const glm::dvec2 c = (uv[0] + uv[1] + uv[2]) / 3.0;
        const BaseSample<double> s = sc.base.evaluate<double>(m.triangleFaces[static_cast<std::size_t>(j)], c.x, c.y, false);
        if (glm::dot(glm::cross(p1 - p0, p2 - p0), glm::cross(s.du, s.dv)) < 0.0) ++r.againstNormal;
        r.signedVolume += glm::dot(p0, glm::cross(p1, p2)) / 6.0;
    }
    for (std::size_t i = 0; i < m.positions.size(); ++i) {
        if (!used[i]) ++r.unreferenced;
        const glm::dvec3 p = m.positions[i], n = m.normals[i];
        if (!std::isfinite(p.x + p.y + p.z + n.x + n.y + n.z)) ++r.nonFinite;
    }
    for (const auto& [ab, j] : directed) {
        if (directed.count({ab.second, ab.first})) continue;
        ++r.boundaryEdges;
        // Which corners of triangle j are a and b, and the tile edge they share.
        const glm::ivec3 t = m.triangles[static_cast<std::size_t>(j)];
        const auto& uv = m.triangleUVs[static_cast<std::size_t>(j)];
        glm::dvec2 ua{}, ub{};
        for (int i = 0; i < 3; ++i) {
            if (t[i] == ab.first) ua = uv[static_cast<std::size_t>(i)];
            if (t[i] == ab.second) ub = uv[static_cast<std::size_t>(i)];
        }
        const int face = m.triangleFaces[static_cast<std::size_t>(j)];
        bool onBoundary = false;
        for (const auto& [e, y0] : edgesAt(ua))
            for (const auto& [e1, y1] : edgesAt(ub)) {
                if (e != e1) continue;
                const double mid = 0.5 * (y0 + y1);
                const TileTopology::Link* l = topo.linkAt(face, e, mid);
                if (!l || sc.base.isHole(l->tile)) onBoundary = true;
            }
        if (!onBoundary) ++r.crackEdges;
    }
    return r;
}

void requireWatertight(const TriangleMesh& m, const Scene& sc, bool closed) {
    const WatertightReport r = watertight(m, sc);
    CAPTURE(m.vertexCount(), m.triangleCount(), r.boundaryEdges, r.againstNormal);
    CHECK(m.triangleCount() > 0);
    CHECK(r.badIndex == 0);
    CHECK(r.degenerate == 0);
    CHECK(r.unreferenced == 0);
    CHECK(r.sameDirection == 0); // with the crack check: every interior edge has exactly two opposite uses
    CHECK(r.crackEdges == 0);
    CHECK(r.nonFinite == 0);
    CHECK(r.clockwise == 0); // counter-clockwise in every face's (u, v) domain
    if (closed) {
        CHECK(r.boundaryEdges == 0);
        CHECK(r.signedVolume > 0.0); // outward orientation
    }
    // Facing the base normal: all but a few triangles (a bump on a coarse tessellation can
    // fold a sliver).
    CHECK(r.againstNormal <= m.triangleCount() / 100);
}

const char* const kMeshes[] = {"catmark_cube",           "catmark_cube_creases0", "catmark_dart_edgecorner",
                               "catmark_edgecorner",     "catmark_flap",          "catmark_gregory_test2",
                               "catmark_helmet",         "catmark_hole_test1",    "catmark_nonquads",
                               "catmark_pole8",          "catmark_pyramid",       "catmark_quadstrips",
                               "catmark_tent_creases0",  "catmark_toroidal_tet",  "catmark_torus",
                               "catmark_xord_boundary",  "spot_control_mesh",     "catmark_bishop"};

bool isClosed(const ControlMesh& mesh) {
    const Far::TopologyLevel& L = mesh.base();
    for (int e = 0; e < L.GetNumEdges(); ++e)
        if (L.GetEdgeFaces(e).size() != 2) return false;
    return mesh.description().holes.empty();
}

} // namespace

TEST_CASE("edge spacing: integer and fractional even, continuous in T", "[tessellate]") {
    CHECK(edgeSpacing(1.0, Spacing::Integer) == std::vector<double>{0.0, 1.0});
    CHECK(edgeSpacing(2.5, Spacing::Integer) == std::vector<double>{0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0});
    CHECK(edgeSpacing(1.0, Spacing::FractionalEven) == std::vector<double>{0.0, 0.5, 1.0});
    CHECK(edgeSpacing(2.0, Spacing::FractionalEven) == std::vector<double>{0.0, 0.5, 1.0});
    CHECK(edgeSpacing(4.0, Spacing::FractionalEven) == std::vector<double>{0.0, 0.25, 0.5, 0.75, 1.0});
    // T = 5: 6 segments, 2 full ones of 1/5 from each end and two of 0.1 at the middle.
    const std::vector<double> x = edgeSpacing(5.0, Spacing::FractionalEven);
    REQUIRE(x.size() == 7);
    CHECK(x[1] == Approx(0.2));
    CHECK(x[2] == Approx(0.4));
    CHECK(x[3] == 0.5);
    CHECK(x[4] == Approx(0.6));
    for (double T = 1.0; T <= 64.0; T += 0.37) {
        for (Spacing s : {Spacing::Integer, Spacing::FractionalEven}) {
            const std::vector<double> p = edgeSpacing(T, s);
            CAPTURE(T, toString(s));
            CHECK(p.front() == 0.0);
            CHECK(p.back() == 1.0);
            bool increasing = true, symmetric = true;
            for (std::size_t i = 0; i + 1 < p.size(); ++i) increasing = increasing && p[i + 1] > p[i];
            for (std::size_t i = 0; i < p.size(); ++i) symmetric = symmetric && std::abs(p[i] + p[p.size() - 1 - i] - 1.0) < 1e-15;
            CHECK(increasing);
            CHECK(symmetric);
        }
    }
    // Continuity: inside a bin the points move by at most |dT| / T (i/T for i <= T/2); across
    // an even T the two new points are born at the midpoint, every other point moves O(dT).
    const double eps = 1e-9;
    for (double T : {2.0, 4.0, 6.0, 10.0, 3.3, 7.77}) {
        const std::vector<double> a = edgeSpacing(T - eps, Spacing::FractionalEven), b = edgeSpacing(T + eps, Spacing::FractionalEven);
        CAPTURE(T);
        double hausdorff = 0;
        for (const std::vector<double>* from : {&a, &b}) {
            const std::vector<double>& to = from == &a ? b : a;
            for (double p : *from) {
                double d = 1;
                for (double q : to) d = std::min(d, std::abs(p - q));
                hausdorff = std::max(hausdorff, d);
            }
        }
        CHECK(hausdorff < 4 * eps);
        if (a.size() == b.size())
            for (std::size_t i = 0; i < a.size(); ++i) CHECK(std::abs(a[i] - b[i]) < 4 * eps);
    }
    CHECK_THROWS_AS(edgeSpacing(0.5, Spacing::Integer), ArgumentError);
    CHECK_THROWS_AS(edgeSpacing(std::nan(""), Spacing::FractionalEven), ArgumentError);
}

TEST_CASE("tessellation is watertight on every test mesh", "[tessellate]") {
    // The full matrix (2 spacings x uniform/distance factors x 3 mip rules) on the small
    // meshes; one configuration each on the two large ones (bishop, spot) to keep it quick.
    for (const char* name : kMeshes) {
        const bool large = std::strcmp(name, "catmark_bishop") == 0 || std::strcmp(name, "spot_control_mesh") == 0;
        const auto sc = makeScene(name);
        const bool closed = isClosed(sc->mesh);
        for (Spacing spacing : {Spacing::Integer, Spacing::FractionalEven})
            for (int distance = 0; distance < 2; ++distance)
                for (MipSelection mips : {MipSelection::Off, MipSelection::TessFactor, MipSelection::TexelRatio}) {
                    if (large && (spacing == Spacing::Integer || distance || mips == MipSelection::TexelRatio)) continue;
                    TessellateOptions o;
                    o.spacing = spacing;
                    o.mips = mips;
                    const TessFactors f = distance ? sc->distanceFactors(glm::dvec3(1.3, 0.7, 2.0))
                                                   : uniformTessFactors(sc->base, large ? 2.0 : 3.0);
                    CAPTURE(name, toString(spacing), distance, toString(mips));
                    requireWatertight(tessellate(sc->surface, f, o), *sc, closed);
                }
    }
}

TEST_CASE("tessellation is watertight with mixed tile sizes", "[tessellate]") {
    for (const char* name : {"catmark_nonquads", "catmark_torus", "catmark_pole8", "catmark_xord_boundary", "catmark_helmet"}) {
        const auto sc = makeScene(name, true);
        bool mixed = false;
        for (const Tile& t : sc->tiles.tiles) mixed = mixed || t.k != sc->tiles.tiles.front().k;
        CHECK(mixed);
        for (MipSelection mips : {MipSelection::Off, MipSelection::TessFactor, MipSelection::TexelRatio}) {
            TessellateOptions o;
            o.mips = mips;
            o.spacing = mips == MipSelection::TexelRatio ? Spacing::Integer : Spacing::FractionalEven;
            CAPTURE(name, toString(mips), toString(o.spacing));
            requireWatertight(tessellate(sc->surface, sc->distanceFactors(glm::dvec3(2, 1, 3)), o),
                              *sc, isClosed(sc->mesh));
        }
    }
}

TEST_CASE("shared vertices: every face around them evaluates the same point", "[tessellate]") {
    // A vertex on a tile edge or corner is evaluated once, by one of its faces. Evaluated from
    // every other face at the linked parameter and with that face's resolution, it must be
    // the same point: s is C0 across patches (regular patches share control points, end caps
    // interpolate the same boundary curves), D is C0 (both tiles hold the coefficients the
    // edge reads, §4.4 clamp equal on both sides) and rho is equal by the per-vertex rule, so
    // only rounding remains (plus |D| |dN_s| wherever N_s were discontinuous across a patch
    // edge, which it is not measurably here, end caps included). Measured worst: 1.4e-13 of a
    // face's size (pole8, valence 8), rho equal to 4.4e-16; the bounds are 1e-10 of a face
    // (a thousand-fold margin over double rounding of the patch sums) and 1e-12.
    for (const char* name : {"catmark_nonquads", "catmark_pole8", "catmark_xord_boundary", "catmark_edgecorner", "catmark_helmet"}) {
        for (bool mixed : {false, true}) {
            const auto sc = makeScene(name, mixed);
            const TileTopology& topo = sc->base.topology();
            for (MipSelection mips : {MipSelection::Off, MipSelection::TessFactor, MipSelection::TexelRatio}) {
                TessellateOptions o;
                o.mips = mips;
                const Tessellator tess(sc->surface, sc->distanceFactors(glm::dvec3(2, -1, 3)), o);
                const TriangleMesh m = tess.tessellate();
                double worst = 0, worstRho = 0;
                int compared = 0;
                for (int i = 0; i < m.vertexCount(); ++i) {
                    const int f = m.faces[static_cast<std::size_t>(i)];
                    const glm::dvec2 uv = m.uvs[static_cast<std::size_t>(i)];
                    const double rho = m.resolutions[static_cast<std::size_t>(i)] + topo.scale(f);
                    for (const auto& [t, q] : samePoint(topo, f, uv)) {
                        if (t == f || sc->base.isHole(t)) continue;
                        const double r = tess.resolution(t, q.x, q.y);
                        const SurfaceSample<double> s = sc->surface.evaluate<double>(t, q.x, q.y, o.normals, r);
                        worst = std::max(worst, glm::length(s.position - m.positions[static_cast<std::size_t>(i)]));
                        if (mips != MipSelection::Off) worstRho = std::max(worstRho, std::abs(r + topo.scale(t) - rho));
                        ++compared;
                    }
                }
                CAPTURE(name, mixed, toString(mips), compared, worst / sc->size, worstRho);
                CHECK(compared > 0);
                CHECK(worst <= 1e-10 * sc->size);
                CHECK(worstRho <= 1e-12);
            }
        }
    }
}

TEST_CASE("fractional spacing: the tessellation moves continuously with T", "[tessellate]") {
    const auto sc = makeScene("catmark_cube");
    const double eps = 1e-7;
    for (MipSelection mips : {MipSelection::Off, MipSelection::TessFactor}) {
        TessellateOptions o;
        o.mips = mips;
        // Inside a bin: the same triangles, every vertex moves O(dT).
        for (double T : {3.1, 5.5, 7.9}) {
            const TriangleMesh a = tessellate(sc->surface, uniformTessFactors(sc->base, T), o);
            const TriangleMesh b = tessellate(sc->surface, uniformTessFactors(sc->base, T + eps), o);
            REQUIRE(a.triangles == b.triangles);
            double moved = 0;
            for (std::size_t i = 0; i < a.positions.size(); ++i) moved = std::max(moved, glm::length(a.positions[i] - b.positions[i]));
            CAPTURE(T, toString(mips), moved / eps);
            CHECK(moved > 0.0);
            CHECK(moved <= 10.0 * sc->size * eps);
        }
        // Across an even T: new vertices are born on old ones, so the piecewise-linear surface
        // at fixed parameters (and its vertex set) stays within O(dT).
        for (double T : {4.0, 6.0}) {
            const TriangleMesh a = tessellate(sc->surface, uniformTessFactors(sc->base, T - eps), o);
            const TriangleMesh b = tessellate(sc->surface, uniformTessFactors(sc->base, T + eps), o);
            CHECK(b.vertexCount() > a.vertexCount());
            const TriangleLocator la(a, sc->base.faceCount()), lb(b, sc->base.faceCount());
            std::mt19937 rng(5);
            std::uniform_real_distribution<double> U(0, 1);
            double jump = 0;
            for (int i = 0; i < 2000; ++i) {
                const int f = static_cast<int>(rng() % 6u);
                const glm::dvec2 uv(U(rng), U(rng));
                jump = std::max(jump, glm::length(la.position(f, uv) - lb.position(f, uv)));
            }
            double hausdorff = 0;
            for (const glm::dvec3& p : b.positions) {
                double d = 1e300;
                for (const glm::dvec3& q : a.positions) d = std::min(d, glm::length(p - q));
                hausdorff = std::max(hausdorff, d);
            }
            CAPTURE(T, toString(mips), jump / eps, hausdorff / eps);
            CHECK(jump <= 10.0 * sc->size * eps);
            CHECK(hausdorff <= 10.0 * sc->size * eps);
        }
    }
}

TEST_CASE("swimming: mip selection holds the surface still while T changes", "[tessellate]") {
    // A cube with a displacement of 9 cycles per face (tiles 2^5) swept over T = 4..8 at
    // fractional even spacing. Measured (256 samples, dT = 1/4): RMS swim 6.8e-2 without mips,
    // 8.6e-3 with rho = log2 TF (0.126 of it) and 8.4e-3 with the texel-ratio rule, against 8.4e-3 for the
    // base surface alone (D = 0): with mips nearly all the swimming left is that of the
    // piecewise-linear base surface. Max swim 0.31 without mips, 0.043 with. Mean error against
    // the finest surface 3.1e-2 without mips, 2.8e-2 with either rule (filtering the bumps a
    // coarse tessellation cannot show costs nothing here).
    ControlMesh mesh = dmtest::shape("catmark_cube");
    const std::vector<int> k = uniformTileSizes(mesh, 5);
    const Scene sc(std::move(mesh), k,
                   [](int f, double u, double v) {
                       const double tau = 6.283185307179586;
                       return 0.04 * std::cos(tau * 9 * (u + v)) + 0.03 * std::sin(tau * 3 * u + f) * std::sin(tau * 2 * v);
                   },
                   1.0);
    SwimOptions o;
    o.tMin = 4;
    o.tMax = 8;
    o.dT = 0.25;
    o.samples = 256;
    const std::vector<SwimRow> rows = measureSwimming(sc.surface, o);
    REQUIRE(rows.size() == 4);
    CHECK(rows[0].baseline);
    const SwimRow &base = rows[0], &off = rows[1], &paper = rows[2], &seed = rows[3];
    std::ostringstream table;
    printSwimTable(table, rows, "");
    INFO(table.str());
    CHECK(off.tessellations == 17);
    CHECK(paper.rmsSwim < 0.25 * off.rmsSwim);
    CHECK(seed.rmsSwim < 0.25 * off.rmsSwim);
    CHECK(paper.maxSwim < 0.5 * off.maxSwim);
    CHECK(base.rmsSwim < 1.1 * paper.rmsSwim);
    CHECK(paper.rmsSwim < 1.1 * base.rmsSwim);
    CHECK(paper.meanError < 1.1 * off.meanError);
    // The CSV has a header and one line per row.
    dmtest::TempDir dir("dispmap_swim_");
    printSwimTable(table, rows, dir.file("swim.csv"));
    const std::vector<unsigned char> csv = dmtest::readBytes(dir.file("swim.csv"));
    CHECK(std::count(csv.begin(), csv.end(), '\n') == 5);
}

TEST_CASE("OBJ and PLY writers round-trip", "[tessellate]") {
    const auto sc = makeScene("catmark_nonquads");
    const TriangleMesh m = tessellate(sc->surface, uniformTessFactors(sc->base, 3.0));
    dmtest::TempDir dir("dispmap_tess_");

    writeObj(m, dir.file("t.obj"));
    const std::vector<unsigned char> objBytes = dmtest::readBytes(dir.file("t.obj"));
    const std::string text(objBytes.begin(), objBytes.end());
    const MeshDescription d = parseObj(text, "t.obj");
    REQUIRE(d.positions.size() == m.positions.size());
    REQUIRE(d.faceSizes.size() == m.triangles.size());
    // The project's reader (tinyobjloader, single precision) sees the same mesh ...
    bool same = true;
    for (std::size_t i = 0; i < m.positions.size(); ++i)
        same = same && glm::length(d.positions[i] - m.positions[i]) <= 1e-6 * (1.0 + glm::length(m.positions[i]));
    for (std::size_t j = 0; j < m.triangles.size(); ++j)
        for (int i = 0; i < 3; ++i) same = same && d.faceSizes[j] == 3 && d.faceVertices[3 * j + static_cast<std::size_t>(i)] == m.triangles[j][i];
    CHECK(same);
    // ... and the decimals are the shortest round-trip ones: read as double, bit for bit.
    std::istringstream lines(text);
    std::string line;
    std::size_t vs = 0, vns = 0;
    bool exact = true;
    while (std::getline(lines, line)) {
        const bool isNormal = line.rfind("vn ", 0) == 0;
        if (!isNormal && line.rfind("v ", 0) != 0) continue;
        std::istringstream in(line.substr(isNormal ? 3 : 2));
        glm::dvec3 x;
        in >> x.x >> x.y >> x.z;
        std::size_t& count = isNormal ? vns : vs;
        const MeshArray<glm::dvec3>& want = isNormal ? m.normals : m.positions;
        exact = exact && count < want.size() && x == want[count];
        ++count;
    }
    CHECK(vs == m.positions.size());
    CHECK(vns == m.normals.size());
    CHECK(exact);

    writePly(m, dir.file("t.ply"));
    const std::vector<unsigned char> ply = dmtest::readBytes(dir.file("t.ply"));
    const std::string head(ply.begin(), ply.begin() + static_cast<std::ptrdiff_t>(std::min<std::size_t>(ply.size(), 1024)));
    const std::size_t end = head.find("end_header\n");
    REQUIRE(end != std::string::npos);
    CHECK(head.rfind("ply\nformat binary_little_endian 1.0\n", 0) == 0);
    CHECK(head.find("element vertex " + std::to_string(m.vertexCount()) + "\n") != std::string::npos);
    CHECK(head.find("element face " + std::to_string(m.triangleCount()) + "\n") != std::string::npos);
    std::size_t at = end + 11;
    REQUIRE(ply.size() == at + m.positions.size() * 24 + m.triangles.size() * 13);
    auto u32 = [&]() {
        std::uint32_t w = 0;
        for (int i = 0; i < 4; ++i) w |= std::uint32_t(ply[at++]) << (8 * i);
        return w;
    };
    bool plySame = true;
    for (std::size_t i = 0; i < m.positions.size(); ++i) {
        const glm::dvec3 &p = m.positions[i], &n = m.normals[i];
        for (double x : {p.x, p.y, p.z, n.x, n.y, n.z}) plySame = plySame && std::bit_cast<float>(u32()) == static_cast<float>(x);
    }
    for (const glm::ivec3& t : m.triangles) {
        plySame = plySame && ply[at++] == 3;
        for (int i = 0; i < 3; ++i) plySame = plySame && u32() == static_cast<std::uint32_t>(t[i]);
    }
    CHECK(plySame);
    CHECK(dir.entries() == std::set<std::string>{"t.obj", "t.ply"}); // no temporaries left
}

TEST_CASE("tessellator: bad inputs are rejected with a message", "[tessellate]") {
    const auto sc = makeScene("catmark_cube");
    const BaseSurface& base = sc->base;
    REQUIRE_THROWS_WITH(uniformTessFactors(base, std::nan("")), Catch::Contains("must be finite and > 0"));
    REQUIRE_THROWS_AS(uniformTessFactors(base, 0.0), ArgumentError);
    REQUIRE_THROWS_AS(uniformTessFactors(base, -2.0), ArgumentError);
    REQUIRE_THROWS_AS(uniformTessFactors(base, HUGE_VAL), ArgumentError);
    REQUIRE_THROWS_WITH(tessFactorsFromBaseVertices(base, {1.0, 2.0}), Catch::Contains("2 tessellation factors given for 8"));
    REQUIRE_THROWS_WITH(distanceTessFactors(base, glm::dvec3(0, 0, 5), 0.0), Catch::Contains("must be finite and > 0"));
    REQUIRE_THROWS_AS(distanceTessFactors(base, glm::dvec3(std::nan(""), 0, 5), 1.0), ArgumentError);

    TessFactors f = uniformTessFactors(base, 2.0);
    f.values[5] = std::nan("");
    REQUIRE_THROWS_WITH(tessellate(sc->surface, f), Catch::Contains("tile vertex 5") && Catch::Contains("finite and > 0"));
    f.values[5] = 0.0;
    REQUIRE_THROWS_AS(tessellate(sc->surface, f), ArgumentError);
    f.values.pop_back();
    REQUIRE_THROWS_WITH(tessellate(sc->surface, f), Catch::Contains("another mesh"));
    TessellateOptions o;
    o.maxFactor = 0.5;
    REQUIRE_THROWS_WITH(tessellate(sc->surface, uniformTessFactors(base, 2.0), o), Catch::Contains("out of range [1, 1024]"));
    o.maxFactor = std::nan("");
    REQUIRE_THROWS_AS(tessellate(sc->surface, uniformTessFactors(base, 2.0), o), ArgumentError);
    const Tessellator tess(sc->surface, uniformTessFactors(base, 2.0));
    REQUIRE_THROWS_WITH(tess.cornerFactors(6), Catch::Contains("out of range [0, 6)"));
    REQUIRE_THROWS_AS(tess.resolution(-1, 0.5, 0.5), ArgumentError);
    CHECK(tess.edgeFactors(0) == glm::dvec4(2.0));

    const TriangleMesh m = tessellate(sc->surface, uniformTessFactors(base, 2.0));
    dmtest::TempDir dir("dispmap_tess_bad_");
    const std::string missing = dir.file("no/such/dir/t.obj");
    REQUIRE_THROWS_WITH(writeObj(m, missing), Catch::Contains("cannot write OBJ mesh '" + missing + "'"));
    REQUIRE_THROWS_WITH(writePly(m, dir.file("none/t.ply")), Catch::Contains("cannot write PLY mesh"));
    TriangleMesh broken = m;
    broken.triangles.back().z = broken.vertexCount();
    REQUIRE_THROWS_WITH(writeObj(broken, dir.file("b.obj")), Catch::Contains("refers to vertex"));
    CHECK(dir.entries().empty());

    SwimOptions so;
    so.tMin = 4;
    so.tMax = 2;
    REQUIRE_THROWS_WITH(measureSwimming(sc->surface, so), Catch::Contains("is invalid"));
}

TEST_CASE("tessellator: a surface that is not finite is named, whatever the route and thread count, and the mesh left empty",
          "[tessellate]") {
    // Tile 3 holds infinite coefficients (tiles edited after the build: buildTiles itself
    // refuses such samples), so every vertex evaluated in face 3 is infinite: the grid's, by
    // evaluateGrid's rows (approximate normals), and by evaluate() (accurate normals), and
    // those on its edges. The first of them in index order is named.
    const ControlMesh mesh = dmtest::shape("catmark_cube");
    const BaseSurface base(mesh);
    const TileSet good = buildTiles(mesh, uniformTileSizes(mesh, 3), dmtest::roughSource);
    TileSet tiles = good;
    for (float& c : tiles.tiles[3].coefficients) c = std::numeric_limits<float>::infinity();
    const DisplacedSurface fine(base, good), surface(base, tiles);
    TriangleMesh used = tessellate(fine, uniformTessFactors(base, 8.0)); // a mesh in use: emptied by the throw
    for (const NormalMode mode : {NormalMode::Approximate, NormalMode::Accurate})
        for (const int threads : {1, 2}) {
            CAPTURE(toString(mode), threads);
            TessellateOptions o;
            o.normals = mode;
            o.threads = threads;
            const Tessellator tess(surface, uniformTessFactors(base, 8.0), o);
            REQUIRE_THROWS_WITH(tess.tessellate(used), Catch::Contains("not finite at Ptex face 3"));
            CHECK(used.vertexCount() == 0);
            CHECK(used.triangleCount() == 0);
            CHECK(used.triangleUVs.empty());
        }
}

} // namespace dmtest_tessellate
