// Mesostructure on curved bases, on the CPU: the frame kernels of kernels/meso_shade.h
// (dmFrameCoordinates, dmFramePoint, dmFrameNormal) against double solves and finite
// differences, FrameMesh (surface/frame_mesh.h) against its surface's derivatives on real
// cages, hard shapes and bad inputs, and the "base" object of mesostructure scenes.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <string>

#include "dispmap/kernels/meso.h"
#include "dispmap/kernels/meso_shade.h"
#include "dispmap/scene/meso.h"
#include "dispmap/surface/frame_mesh.h"
#include "dispmap/surface/tessellator.h"
#include "test_files.h"
#include "test_support.h"

namespace frame_mesh_test {
namespace {
using namespace dispmap;
using Catch::Contains;

// A surface of a control mesh with zero displacement (the limit surface) or a gentle wave,
// tessellated uniformly.
struct Built {
    ControlMesh mesh;
    BaseSurface base;
    TileSet tiles;
    DisplacedSurface surface;
    TriangleMesh tess;
    Built(ControlMesh m, double factor, double wave = 0.0)
        : mesh(std::move(m)), base(mesh), tiles(buildTiles(mesh, uniformTileSizes(mesh, 3), FunctionSource([wave](int, double u, double v) {
                                                  return wave * std::sin(6.0 * u) * std::cos(5.0 * v);
                                              }))),
          surface(base, tiles), tess(Tessellator(surface, uniformTessFactors(base, factor)).tessellate()) {}
};

glm::dvec3 randomVec(std::mt19937& g, double scale) {
    std::uniform_real_distribution<double> u(-scale, scale);
    return {u(g), u(g), u(g)};
}

// A random frame: tangents of lengths 0.05 .. 5 at least ~6 degrees out of each other's and the
// normal's plane, mirrored half of the time.
void randomFrame(std::mt19937& g, glm::dvec3& pS, glm::dvec3& pT, glm::dvec3& n) {
    do {
        pS = randomVec(g, 1.0) * std::exp(std::uniform_real_distribution<double>(-3.0, 1.6)(g));
        pT = randomVec(g, 1.0) * std::exp(std::uniform_real_distribution<double>(-3.0, 1.6)(g));
        n = glm::normalize(glm::cross(pS, pT) + randomVec(g, 0.5) * glm::length(glm::cross(pS, pT)));
        if (g() & 1u) n = -n;
    } while (frameIndependence(pS, pT, n) < 0.1);
}

TEST_CASE("dmFrameCoordinates solves w = a pS + b pT + c n", "[meso][frame]") {
    std::mt19937 g(7);
    double worstD = 0, worstF = 0;
    for (int i = 0; i < 2000; ++i) {
        glm::dvec3 pS, pT, n;
        randomFrame(g, pS, pT, n);
        const glm::dvec3 w = randomVec(g, 3.0);
        const glm::dvec3 c = kern::dmFrameCoordinates(w, pS, pT, n);
        const double scale = glm::length(w);
        worstD = std::max(worstD, glm::length(c.x * pS + c.y * pT + c.z * n - w) / scale);
        // Float against the double solve: each coordinate's error measured in its own vector's
        // length, relative to |w|.
        const glm::vec3 cf = kern::dmFrameCoordinates(glm::vec3(w), glm::vec3(pS), glm::vec3(pT), glm::vec3(n));
        const glm::dvec3 e = glm::dvec3(cf) - c;
        worstF = std::max(worstF, glm::length(e.x * pS + e.y * pT + e.z * n) / scale);
    }
    INFO("worst residual: double " << worstD << ", float " << worstF);
    // Cramer's rule on frames at least 0.1 from singular: double within 1e-13 (a few hundred
    // ULP, condition <= 10 over ~10 operations), float within 1e-5 (same count of float ULP).
    CHECK(worstD < 1e-13);
    CHECK(worstF < 1e-5);

    // On the plane's frame (pS = tile x, pT = tile y, n = z) the ray is the plane's own
    // (dmTangentToVoxel with W / tile): the two routes agree to float rounding.
    const double tile = 0.5;
    const glm::vec3 vpuFrame(64.0f, 64.0f, 200.0f), vpuPlane(128.0f, 128.0f, 200.0f);
    for (int i = 0; i < 200; ++i) {
        glm::dvec3 w = randomVec(g, 2.0);
        w.z = -std::abs(w.z) - 0.01;
        const glm::vec3 a = kern::dmTangentToVoxel(
            kern::dmFrameCoordinates(glm::vec3(w), glm::vec3(float(tile), 0.0f, 0.0f), glm::vec3(0.0f, float(tile), 0.0f), glm::vec3(0.0f, 0.0f, 1.0f)),
            vpuFrame);
        const glm::vec3 b = kern::dmTangentToVoxel(glm::vec3(w), vpuPlane);
        CHECK(glm::length(a - b) < 1e-6f); // unit vectors: a few float ULP
    }
}

TEST_CASE("dmFramePoint takes a voxel-space offset back to the world", "[meso][frame]") {
    std::mt19937 g(11);
    const glm::dvec3 vpu(64.0, 32.0, 160.0);
    for (int i = 0; i < 500; ++i) {
        glm::dvec3 pS, pT, n;
        randomFrame(g, pS, pT, n);
        const glm::dvec3 base = randomVec(g, 5.0), o = randomVec(g, 100.0), q = randomVec(g, 20.0);
        const glm::dvec3 x = kern::dmFramePoint(base, o + q, o, pS, pT, n, vpu);
        // Its frame coordinates, scaled to voxels, are the offset again: double rounding of
        // O(1e2) voxel offsets through a frame at least 0.1 from singular and back, ~1e-13;
        // 1e-9 relative leaves room and still catches any wrong scale or sign.
        const glm::dvec3 c = kern::dmFrameCoordinates(x - base, pS, pT, n) * vpu;
        CHECK(glm::length(c - q) < 1e-9 * (1.0 + glm::length(q)));
    }
}

TEST_CASE("dmFrameNormal is the normal of the height field over the frame", "[meso][frame]") {
    std::mt19937 g(5);
    const glm::dvec3 vpu(64.0, 48.0, 16.0 / 0.05);
    double worst = 0;
    for (int i = 0; i < 500; ++i) {
        glm::dvec3 pS, pT, n;
        randomFrame(g, pS, pT, n);
        std::uniform_real_distribution<double> u(0.0, 1.0);
        const glm::dvec4 h(16 * u(g), 16 * u(g), 16 * u(g), 16 * u(g));
        const glm::dvec2 f(u(g), u(g));
        // X(f) = (f.x / W) pS + (f.y / H) pT + (bilinear height / (L / depth)) n; the height is
        // linear along each of f.x and f.y, so central differences are exact up to rounding.
        const auto X = [&](glm::dvec2 p) { return (p.x / vpu.x) * pS + (p.y / vpu.y) * pT + (kern::dmBilerp(h, p) / vpu.z) * n; };
        const double e = 1e-4;
        glm::dvec3 m = glm::cross(X(f + glm::dvec2(e, 0)) - X(f - glm::dvec2(e, 0)), X(f + glm::dvec2(0, e)) - X(f - glm::dvec2(0, e)));
        if (glm::dot(m, n) < 0) m = -m;
        worst = std::max(worst, glm::length(glm::normalize(m) - kern::dmFrameNormal(h, f, pS, pT, n, vpu)));
    }
    INFO("worst difference " << worst);
    CHECK(worst < 1e-8); // differences of 1e-4 steps of O(1) values: ~1e-12 / 1e-4 relative

    // On the plane's frame it is the plane's dmMesoWorldNormal (voxels per world unit W / tile).
    const glm::dvec4 h(3.0, 7.5, 2.0, 9.0);
    const glm::dvec2 f(0.3, 0.8);
    const glm::dvec3 a = kern::dmFrameNormal(h, f, glm::dvec3(0.5, 0, 0), glm::dvec3(0, 0.5, 0), glm::dvec3(0, 0, 1), glm::dvec3(64, 64, 320));
    const glm::dvec3 b = kern::dmMesoWorldNormal(h, f, glm::dvec3(128, 128, 320));
    CHECK(glm::length(a - b) < 1e-15);
}

// The frame's defining property at a corner: the surface's derivatives along the face's u and
// v (central differences of evaluated positions) are pS s_u + pT t_u and pS s_v + pT t_v,
// with the chart's derivatives (s, t)_u, (s, t)_v.
double worstDerivativeError(const Built& b, const FrameMesh& fm, const UvMap* uv, glm::dvec2 repeat, std::size_t stride) {
    double worst = 0;
    const double h = 1e-5;
    for (std::size_t i = 0; i < fm.corners.size(); i += stride) {
        const std::size_t t = i / 3;
        const int face = b.tess.triangleFaces[t];
        // At the triangle's centre: its corners lie on patch boundaries, where Gregory end caps
        // meet their neighbours with G1, not C1, and next to an extraordinary vertex a Gregory
        // patch's rational weights make central differences useless (errors of 1e-2 at 1e-3
        // from the vertex).
        const auto& uvs = b.tess.triangleUVs[t];
        const glm::dvec2 p = (uvs[0] + uvs[1] + uvs[2]) / 3.0;
        const auto P = [&](double u, double v) { return b.surface.evaluate(face, u, v, NormalMode::Accurate).position; };
        const glm::dvec3 fu = (P(p.x + h, p.y) - P(p.x - h, p.y)) / (2 * h), fv = (P(p.x, p.y + h) - P(p.x, p.y - h)) / (2 * h);
        glm::dvec2 su{repeat.x, 0.0}, sv{0.0, repeat.y};
        if (uv) {
            const UvSample w = uv->evaluate(face, p.x, p.y);
            su = w.du * repeat;
            sv = w.dv * repeat;
        }
        // The frame there, as buildFrameMesh computes it.
        FrameVertex v;
        FrameMeshOptions o;
        o.repeat = repeat;
        o.placement = uv ? FramePlacement::Uv : FramePlacement::Face;
        if (!detail::frameAt(b.surface, uv, o, face, p, p, v)) continue; // a singular chart point (nudged in the mesh)
        const double scale = glm::length(fu) + glm::length(fv);
        worst = std::max(worst, (glm::length(v.pS * su.x + v.pT * su.y - fu) + glm::length(v.pS * sv.x + v.pT * sv.y - fv)) / scale);
        // And the mesh's corner is the frame at the corner itself (where it is not singular).
        FrameVertex c;
        if (detail::frameAt(b.surface, uv, o, face, uvs[i % 3], uvs[i % 3], c))
            CHECK((fm.corners[i].pS == c.pS && fm.corners[i].pT == c.pT && fm.corners[i].normal == c.normal));
    }
    return worst;
}

void checkSane(const FrameMesh& fm, const TriangleMesh& tess) {
    REQUIRE(fm.corners.size() == 3 * tess.triangles.size());
    std::size_t bad = 0;
    for (std::size_t i = 0; i < fm.corners.size(); ++i) {
        const FrameVertex& v = fm.corners[i];
        const bool finite = std::isfinite(glm::dot(v.pS + v.pT + v.normal + v.position, glm::dvec3(1))) && std::isfinite(v.tex.x + v.tex.y);
        const bool ok = finite && std::abs(glm::length(v.normal) - 1.0) < 1e-9 && frameIndependence(v.pS, v.pT, v.normal) >= kMinFrameIndependence &&
                        v.position == tess.positions[static_cast<std::size_t>(tess.triangles[i / 3][static_cast<int>(i % 3)])];
        bad += ok ? 0u : 1u;
    }
    CHECK(bad == 0);
}

TEST_CASE("a frame mesh's frames are its surface's derivatives in the texture's coordinates", "[meso][frame]") {
    SECTION("Spot, by its UVs, on the limit surface") {
        const Built b(dmtest::shape("spot_control_mesh"), 4.0);
        const UvMap uv(b.mesh);
        const FrameMesh fm = buildFrameMesh(b.surface, b.tess, &uv, {FramePlacement::Uv, {8.0, 8.0}, NormalMode::Accurate});
        checkSane(fm, b.tess);
        const double worst = worstDerivativeError(b, fm, &uv, {8.0, 8.0}, 7);
        INFO("worst relative derivative error " << worst);
        // Central differences with h = 1e-5: truncation O(h^2 |f'''|) and rounding
        // O(1e-16 / 1e-5): ~1e-9 relative; the end caps' Gregory patches are smooth inside.
        CHECK(worst < 1e-6);
        // Texture coordinates: the UVs times the repeat, moved by whole tiles so that each
        // triangle's smallest is in [0, 1).
        for (std::size_t i = 0; i < fm.corners.size(); i += 101) {
            const glm::dvec2 p = b.tess.triangleUVs[i / 3][i % 3];
            const glm::dvec2 shift = fm.corners[i].tex - uv(b.tess.triangleFaces[i / 3], p.x, p.y) * 8.0;
            CHECK(glm::length(shift - glm::round(shift)) < 1e-12);
        }
        for (std::size_t t = 0; t < fm.corners.size(); t += 3) {
            const glm::dvec2 lo = glm::min(glm::min(fm.corners[t].tex, fm.corners[t + 1].tex), fm.corners[t + 2].tex);
            CHECK((lo.x >= 0 && lo.x < 1 && lo.y >= 0 && lo.y < 1));
        }
    }
    SECTION("the torus cage of tests/data, displaced, by its UVs with smooth UV rules") {
        const Built b(dmtest::shape("catmark_torus"), 3.0, 0.05);
        const UvMap uv(b.mesh, UvInterpolation::Smooth);
        const FrameMesh fm = buildFrameMesh(b.surface, b.tess, &uv, {FramePlacement::Uv, {2.0, 3.0}, NormalMode::Accurate});
        checkSane(fm, b.tess);
        const double worst = worstDerivativeError(b, fm, &uv, {2.0, 3.0}, 3);
        INFO("worst relative derivative error " << worst);
        CHECK(worst < 1e-6);
    }
    SECTION("every face its own tiles, extraordinary vertices and N-gons") {
        const Built b(dmtest::shape("catmark_nonquads"), 4.0, 0.02);
        const FrameMesh fm = buildFrameMesh(b.surface, b.tess, nullptr, {FramePlacement::Face, {2.0, 2.0}, NormalMode::Accurate});
        checkSane(fm, b.tess);
        CHECK(worstDerivativeError(b, fm, nullptr, {2.0, 2.0}, 5) < 1e-6);
        for (std::size_t i = 0; i < fm.corners.size(); i += 13) {
            const glm::dvec2 shift = fm.corners[i].tex - b.tess.triangleUVs[i / 3][i % 3] * 2.0;
            CHECK(shift == glm::round(shift)); // (u, v) times 2, whole tiles off
        }
    }
}

TEST_CASE("dmShellExit: where a ray leaves the curved shell through its top", "[meso][frame][silhouette]") {
    SECTION("a cylinder's exact shell: a ray from the top leaves where it crosses the circle again") {
        // Radius R, tiles of T world units along the circle: n . P_ss = -T^2 / R, the most convex
        // principal curvature -1 / R. A voxel offset (x, z) is T x / W along the circle's tangent
        // and z / vpu.z along n: the ray leaves the disc of radius R at
        // t = -2 R d_n / (d_a^2 + d_n^2), d_a = d.x T / W, d_n = d.z / vpu.z.
        const double R = 2.0, T = 0.3;
        const glm::dvec3 vpu(64.0, 64.0, 16.0 / 0.05), o(10.0, 20.0, 16.0);
        const glm::dvec4 shape(-T * T / R, 0.0, 0.0, -1.0 / R);
        for (const glm::dvec3 d : {glm::dvec3(1, 0, -0.1), glm::dvec3(1, 0, -30.0), glm::dvec3(-3, 0, -0.02), glm::dvec3(0.2, 0, -1.0)}) {
            const double da = d.x * T / vpu.x, dn = d.z / vpu.z;
            CHECK(kern::dmShellExit(o, d, o, shape, vpu, 16.0) == Approx(-2.0 * R * dn / (da * da + dn * dn)).epsilon(1e-12));
            // The osculating paraboloid alone (m = 0) leaves later: 2 d.z / (d^T K d).
            const double kxx = shape.x * vpu.z / (vpu.x * vpu.x);
            CHECK(kern::dmShellExit(o, d, o, glm::dvec4(glm::dvec3(shape), 0.0), vpu, 16.0) == Approx(2.0 * d.z / (kxx * d.x * d.x)).epsilon(1e-12));
        }
        // Along the cylinder's axis only the vertical term bends: straight down, the ray leaves
        // the disc at its far side, 2 R deep; a ray going up leaves at once.
        CHECK(kern::dmShellExit(o, glm::dvec3(0, 0, -1), o, shape, vpu, 16.0) == Approx(2.0 * R * vpu.z).epsilon(1e-12));
        CHECK(kern::dmShellExit(o, glm::dvec3(0, 1, -0.1), o, glm::dvec4(glm::dvec3(shape), 0.0), vpu, 16.0) == -1.0);
        CHECK(kern::dmShellExit(o, glm::dvec3(1, 0, 0.1), o, shape, vpu, 16.0) == 0.0);
        // Concave (the inside of the cylinder): the top rises over a descending ray, no exit.
        CHECK(kern::dmShellExit(o, glm::dvec3(1, 0, -0.1), o, glm::dvec4(-glm::dvec3(shape), 0.0), vpu, 16.0) == -1.0);
    }
    SECTION("a sphere's exact shell, in a sheared chart with W != H: the ray leaves the ball at -2 R (D . n) / |D|^2") {
        // In any chart a sphere's II is -G / R (G the first fundamental form of pS, pT): the
        // K_xy and K_yy terms and the vpu scaling of all three, against the world's closed form.
        std::mt19937 g(11);
        int spheres = 0;
        for (int k = 0; k < 200; ++k) {
            glm::dvec3 pS, pT, n;
            randomFrame(g, pS, pT, n);
            // A sphere's frame: n normal to both tangents (on either side: a mirrored chart).
            n = glm::normalize(glm::cross(pS, pT)) * (glm::dot(n, glm::cross(pS, pT)) < 0 ? -1.0 : 1.0);
            const double R = std::exp(std::uniform_real_distribution<double>(-1.0, 2.0)(g));
            const glm::dvec3 vpu(40.0, 96.0, 16.0 / (0.05 * R));
            const glm::dvec4 shape(-glm::dot(pS, pS) / R, -glm::dot(pS, pT) / R, -glm::dot(pT, pT) / R, -1.0 / R);
            const glm::dvec3 o(5.0, 6.0, 16.0), d = glm::normalize(glm::dvec3(randomVec(g, 1.0).x, randomVec(g, 1.0).y, -0.05 - std::abs(randomVec(g, 1.0).z)));
            const glm::dvec3 D = pS * (d.x / vpu.x) + pT * (d.y / vpu.y) + n * (d.z / vpu.z); // d's world image
            CHECK(kern::dmShellExit(o, d, o, shape, vpu, 16.0) == Approx(-2.0 * R * glm::dot(D, n) / glm::dot(D, D)).epsilon(1e-9));
            ++spheres;
        }
        CHECK(spheres > 100);
    }
    SECTION("a bent ray's point in the slab lies at the world point's depth below a cylinder's or a ball's top") {
        // kern::dmBentPoint with the bend (dmShellBend) and the curve (the most convex curvature
        // in voxels) of the base: at every t at which the straight world ray is inside the shell,
        // the slab height is L - depth vpu.z, the depth R - |X - C| of the world point X.
        // Without the curve (the parabola) the quadric's level is taken for the depth: off by
        // depth^2 / (2 R), a quarter of the depth at the floor at the renderer's limit (and its
        // floor, where the level is the depth, twice as deep as the true one).
        std::mt19937 g(29);
        std::uniform_real_distribution<double> u(-1.0, 1.0);
        const double L = 16.0;
        double worst = 0, worstParabola = 0, worstFloor = 0;
        int points = 0, floors = 0;
        for (int k = 0; k < 400; ++k) {
            const bool ball = k % 2 == 1;
            glm::dvec3 pS(0.3, 0.0, 0.0), pT(0.0, 0.4, 0.0), n(0.0, 0.0, 1.0);
            if (ball) {
                randomFrame(g, pS, pT, n);
                n = glm::normalize(glm::cross(pS, pT)) * (glm::dot(n, glm::cross(pS, pT)) < 0 ? -1.0 : 1.0);
            }
            const double R = std::exp(1.5 * u(g)), delta = R * (0.01 + 0.245 * (1.0 + u(g))); // up to the limit, delta / R = 1/2
            const glm::dvec3 vpu(40.0, 96.0, L / delta);
            // The cylinder's axis along pT (K_yy = 0); the ball: II = -G / R in any chart.
            const glm::dvec4 shape = ball ? glm::dvec4(-glm::dot(pS, pS) / R, -glm::dot(pS, pT) / R, -glm::dot(pT, pT) / R, -1.0 / R)
                                          : glm::dvec4(-glm::dot(pS, pS) / R, 0.0, 0.0, -1.0 / R);
            const glm::dvec3 o(5.0, 6.0, L), d = glm::normalize(glm::dvec3(u(g), u(g), -0.02 - std::abs(u(g))));
            const double bend = kern::dmShellBend(d, shape, vpu), curve = kern::dmShellVoxels(shape, vpu).w;
            const glm::dvec3 P(1.0, 2.0, 3.0), C = P - n * R;
            const glm::dvec3 D = pS * (d.x / vpu.x) + pT * (d.y / vpu.y) + n * (d.z / vpu.z); // d's world image
            // Where the ray meets the slab's floor (kern::dmBentFloor): the world point is delta
            // deep there, where the straight ray reaches the inner circle or ball.
            const double tFloor = kern::dmBentFloor(o, d, bend, curve, -1.0);
            if (tFloor >= 0) {
                const glm::dvec3 X = P + D * tFloor;
                const glm::dvec3 r = ball ? X - C : (X - C) - glm::normalize(pT) * glm::dot(X - C, glm::normalize(pT));
                worstFloor = std::max(worstFloor, std::abs((R - glm::length(r)) - delta) / delta);
                floors += 1;
            }
            for (int i = 1; i <= 200; ++i) {
                const double t = i * 0.5;
                const glm::dvec3 X = P + D * t;
                const glm::dvec3 r = ball ? X - C : (X - C) - glm::normalize(pT) * glm::dot(X - C, glm::normalize(pT));
                const double depth = R - glm::length(r);
                if (depth < 0 || depth > delta) break; // out of the shell
                const double z = kern::dmBentPoint(o, d, bend, curve, t).z, zParabola = kern::dmBentPoint(o, d, bend, 0.0, t).z;
                worst = std::max(worst, std::abs(z - (L - depth * vpu.z)));
                worstParabola = std::max(worstParabola, std::abs(zParabola - (L - depth * vpu.z)));
                ++points;
            }
        }
        INFO(points << " points: worst |z - exact| " << worst << " voxels; the parabola's " << worstParabola << "; " << floors
                    << " floors, worst depth error there " << worstFloor << " delta");
        CHECK(points > 5000);
        CHECK(floors > 100);
        CHECK(worstFloor < 1e-9);
        CHECK(worst < 1e-9 * L);
        CHECK(worstParabola > 0.2 * L); // measured 3.96 voxels of 16
    }
    SECTION("random shells and rays, at both precisions, against a fine walk of the top's height over the ray") {
        std::mt19937 g(17);
        std::uniform_real_distribution<double> u(-1.0, 1.0);
        int exits = 0, none = 0;
        for (int k = 0; k < 4000; ++k) {
            const glm::dvec3 vpu(std::exp(2.0 + 2.0 * u(g)), std::exp(2.0 + 2.0 * u(g)), std::exp(4.0 + 2.0 * u(g)));
            const glm::dvec4 shape(0.02 * u(g), 0.02 * u(g), 0.02 * u(g), (k & 2) ? -0.5 * (1.0 + u(g)) : 0.0);
            const glm::dvec3 o(8.0 * u(g), 8.0 * u(g), 16.0);
            // From the entry, or from a point below the top (a shadow ray's start).
            const glm::dvec3 p = (k & 1) ? o : o + glm::dvec3(4.0 * u(g), 4.0 * u(g), -8.0 - 7.0 * u(g));
            const glm::dvec3 d(u(g), u(g), 0.5 * u(g));
            const double kxx = shape.x * vpu.z / (vpu.x * vpu.x), kxy = shape.y * vpu.z / (vpu.x * vpu.y), kyy = shape.z * vpu.z / (vpu.y * vpu.y);
            const auto top = [&](double t) {
                const glm::dvec2 e = glm::dvec2(p + d * t) - glm::dvec2(o);
                const double z = p.z + d.z * t - 16.0;
                return 0.5 * (kxx * e.x * e.x + 2.0 * kxy * e.x * e.y + kyy * e.y * e.y) + 0.5 * (shape.w / vpu.z) * z * z - z;
            };
            if (!(top(0.0) >= 0)) continue; // a start above the top (the kernel takes it as on it)
            const double t = kern::dmShellExit(p, d, o, shape, vpu, 16.0);
            const float tf = kern::dmShellExit(glm::vec3(p), glm::vec3(d), glm::vec3(o), glm::vec4(shape), glm::vec3(vpu), 16.0f);
            // The walk: the first step at which the top's height over the ray turns negative.
            double walk = -1;
            const double step = 1e-3;
            for (int i = 1; i <= 200000; ++i)
                if (top(i * step) < 0) {
                    walk = i * step;
                    break;
                }
            INFO("k " << k << " t " << t << " walk " << walk);
            if (walk < 0) {
                // Never out within the walk: either no exit, or one beyond it.
                CHECK((t < 0 || t > 199.0));
                ++none;
                continue;
            }
            ++exits;
            // Within a step of the walk, unless the ray only touched the top (a double root).
            CHECK(t <= walk + 1e-9);
            CHECK(t >= walk - step - 1e-9 * walk);
            // Float within its rounding of the double answer (the roots' conditioning is at
            // most 1 / |g'| at the root, and g' is far from 0 for these rays but for a few).
            CHECK(std::abs(double(tf) - t) <= 1e-3 * std::max(1.0, t));
        }
        INFO(exits << " exits, " << none << " none");
        CHECK(exits > 500);
        CHECK(none > 500);
    }
}

// The largest step between two neighbouring samples of `field` (voxels of height per voxel).
double steepestStep(const MesoHeightField& field) {
    double steep = 0;
    for (int j = 0; j < field.height; ++j)
        for (int i = 0; i < field.width; ++i) {
            const glm::vec4 c = field.cell(i, j);
            steep = std::max({steep, double(std::abs(c.y - c.x)), double(std::abs(c.w - c.x)), double(std::abs(c.z - c.y)), double(std::abs(c.z - c.w))});
        }
    return steep;
}

// A reference for marches along a bent ray: the curve kern::dmBentPoint (with curve 0 the
// parabola P(t) = o + t d - bend t^2 z) walked in steps of 1/64 of its parameter over the
// bilinear field (the floor solid). tNear: the first point within `near` of the surface or
// below it; tDeep: the first `deep` below it (-1: none before the ray leaves); leaves: it came
// back above the top first.
struct BentWalk {
    double tNear = -1, tDeep = -1;
    bool leaves = false;
};
// How far P(t) lies below the bilinear surface (< 0: above it); the floor is solid.
double bentBelow(const MesoHeightField& field, const glm::dvec3& o, const glm::dvec3& d, const MesoBend& bend, double t) {
    const glm::dvec3 p = kern::dmBentPoint(o, d, bend.bend, bend.curve, t);
    glm::dvec2 f;
    const glm::ivec2 c = kern::dmHeightCell(glm::dvec2(p.x, p.y), f);
    return std::max(kern::dmBilerp(glm::dvec4(field.cell(c.x, c.y)), f), 0.0) - p.z;
}
BentWalk walkBentRay(const MesoHeightField& field, const glm::dvec3& o, const glm::dvec3& d, const MesoBend& bend, double near, double deep) {
    const auto below = [&](double t) { return bentBelow(field, o, d, bend, t); };
    BentWalk w;
    for (double t = 0.0; t < 4096.0; t += 1.0 / 64.0) {
        const double z = kern::dmBentPoint(o, d, bend.bend, bend.curve, t).z;
        if (t > 0 && z > field.layers) { // back above the top: left the shell
            w.leaves = true;
            break;
        }
        const double b = below(t);
        if (w.tNear < 0 && b >= -near) w.tNear = t;
        if (b >= deep) {
            w.tDeep = t;
            break;
        }
    }
    return w;
}

// A bend of 0 marches the straight ray: the same hit, t and count as marchMeso, bit for bit, at
// both precisions.
void checkUnbentIsStraight(const MesoMaps& maps, const MesoTechnique& tq, const glm::dvec3& o, const glm::dvec3& d) {
    const MesoHit a = marchMesoBent<float>(maps, tq, o, d, 0.0), b = marchMeso<float>(maps, tq, o, d);
    CHECK((a.hit == b.hit && a.t == b.t && a.iterations == b.iterations));
    const MesoHit c = marchMesoBent<double>(maps, tq, o, d, 0.0), e = marchMeso<double>(maps, tq, o, d);
    CHECK((c.hit == e.hit && c.t == e.t && c.iterations == e.iterations));
}

// A bent ray from the top of a slab L deep (MesoBend): where it ends (the floor, D(F) = L at F =
// L + c L^2 / 2, or the top again, F = 0, when a convex bend turns it up first), written out
// here on its own; its depth rate D' at the floor; the bound z'' <= D' (2 |bend| + |c| D'^2
// F'^2) on its curvature (F' = 2 bend t - d.z at its largest).
struct BentEnd {
    double tEnd = 0, rate = 1, zpp = 0;
    bool atTop = false;
};
BentEnd bentEnd(double L, const glm::dvec3& d, const MesoBend& b) {
    BentEnd e;
    const double f = L + 0.5 * b.curve * L * L, disc = d.z * d.z + 4.0 * b.bend * f;
    e.tEnd = b.bend == 0 ? -L / d.z : disc >= 0 ? 2.0 * f / (std::sqrt(disc) - d.z) : -1.0;
    e.atTop = b.bend < 0 && (e.tEnd < 0 || d.z / b.bend < e.tEnd);
    if (e.atTop) e.tEnd = d.z / b.bend;
    e.rate = 1.0 / (1.0 + b.curve * L);
    const double slope = std::max(std::abs(d.z), std::abs(2.0 * b.bend * e.tEnd - d.z));
    e.zpp = e.rate * (2.0 * std::abs(b.bend) + std::abs(b.curve) * e.rate * e.rate * slope * slope);
    return e;
}

TEST_CASE("a bent ray's DDM march finds the bent ray's first crossing of the height field", "[meso][frame][silhouette]") {
    // The grating and a wave field, 4x1 + shadow cones (bent-up chords read them), quadrics. The
    // reference walks the bent ray (kern::dmBentPoint; with curve 0 the parabola o + t d - bend
    // t^2 z) itself in steps of 1/64 of its parameter: the
    // chords lie within e = kMesoChordError (0.05 voxels, vertically) of it (more where 64 chords
    // are too few: |bend| (length / 64)^2 / 4), so the march's hit must
    // lie between the first point where the ray comes within 0.05 of the surface (or the
    // floor) and the first where it is 0.05 below it; a ray that never comes within 0.05
    // of it before it leaves through the top again is a miss, and one that dips 0.05 below is a hit
    // (the walk's "within" widened by what the field can change between two of its points).
    for (const char* function : {"grating", "waves"}) {
        const MesoHeightField field = mesoFunctionField(function, 32, 16);
        const MesoMaps maps = buildMesoMaps(field, mesoMapOptionsFor(MesoTechnique{}, true, ConeSet{4, 1, false, false}));
        MesoTechnique tq;
        tq.iterations = 512;
        const double L = field.layers, eChord = kMesoChordError;
        // The walk's own blind spot: between two of its points (1/64 of a voxel or less apart
        // horizontally) the field changes by at most its steepest texel step / 64 and the ray by
        // its vertical speed / 64 (the depth rate times |F'|, per ray below).
        const double steep = steepestStep(field);
        std::mt19937 g(5);
        std::uniform_real_distribution<double> u(0.0, 1.0);
        int hits = 0, misses = 0, bentUp = 0, straight = 0, checked = 0;
        for (int k = 0; k < 3000; ++k) {
            const double elev = (k % 3 == 0 ? 0.02 + 0.15 * u(g) : 0.1 + 1.3 * u(g)), az = 6.283185307179586 * u(g);
            const glm::dvec3 d(std::cos(elev) * std::cos(az), std::cos(elev) * std::sin(az), -std::sin(elev));
            const glm::dvec3 o(64.0 * u(g) - 16.0, 64.0 * u(g) - 16.0, L);
            // Every third ray's depth follows a convex base's curvature (MesoBend::curve) up to the
            // renderer's limit (c L = -1/2).
            const MesoBend bend(k % 10 == 0 ? 0.0 : (k % 2 == 0 ? -1.0 : 1.0) * std::exp(-9.0 + 7.0 * u(g)), k % 3 == 1 ? -0.5 * u(g) / L : 0.0);
            // The chords' error: kMesoChordError, or more where the march's 64 chords are too few
            // for the curve's length (to the floor, or back to the top: tEnd).
            const BentEnd end = bentEnd(L, d, bend);
            const double tEnd = end.tEnd;
            const double e = std::max(eChord, end.zpp * (tEnd / 64.0) * (tEnd / 64.0) / 8.0);
            const double walkSlack = (steep + end.rate * (std::abs(d.z) + 2.0 * std::abs(bend.bend) * tEnd)) / 64.0;
            const BentWalk w = walkBentRay(field, o, d, bend, e + walkSlack, e);
            const double tNear = w.tNear, tDeep = w.tDeep;
            const bool leaves = w.leaves;
            glm::dvec3 slab;
            const MesoHit h = marchMesoBent<double>(maps, tq, o, d, bend, &slab);
            INFO(function << " k " << k << " bend " << bend.bend << " curve " << bend.curve << " hit " << h.hit << " t " << h.t << " n " << h.iterations
                          << " near " << tNear << " deep " << tDeep);
            bentUp += bend.bend < 0 && leaves ? 1 : 0;
            straight += bend.bend == 0 ? 1 : 0;
            if (tNear < 0) {
                CHECK_FALSE(h.hit);
                ++misses;
                continue;
            }
            if (tDeep >= 0) {
                REQUIRE(h.hit);
                ++hits;
                // t on the straight ray is the bent ray's parameter: between the two walk points
                // (one step of slack either side).
                CHECK(h.t >= tNear - 1.0 / 64.0);
                CHECK(h.t <= tDeep + 1.0 / 64.0);
                // The hit's slab point is on the curve to the chords' error.
                const glm::dvec3 p = kern::dmBentPoint(o, d, bend.bend, bend.curve, h.t);
                CHECK(glm::length(slab - p) <= e + 1e-9 * (1.0 + h.t));
                ++checked;
            }
        }
        INFO(function << ": " << hits << " hits, " << misses << " misses, " << bentUp << " rays bent back out, " << straight << " straight");
        CHECK(hits > 1000);
        CHECK(misses > 50);
        CHECK(bentUp > 50);
        CHECK(checked == hits);
    }
    // Rays over a convex base whose whole dip stays within the chord error of the top (one chord
    // from the entry back to the top, every pixel at an outline): none reaches the grating's
    // highest wall (14 of 16 layers), so every one misses, at both precisions. (The single
    // chord's end may round a float step below the top; it once marched along the top layer
    // until its iterations ran out, a hit hundreds of voxels away.)
    {
        const MesoMaps grating = buildMesoMaps(mesoFunctionField("grating", 32, 16), mesoMapOptionsFor(MesoTechnique{}, true, ConeSet{4, 1, false, false}));
        MesoTechnique tq;
        tq.iterations = 128;
        std::mt19937 g(23);
        std::uniform_real_distribution<double> u(0.0, 1.0);
        int falseHits = 0;
        for (int k = 0; k < 100000; ++k) {
            const double bend = -std::exp(-9.0 + 8.0 * u(g)), az = 6.283185307179586 * u(g);
            const double dz = -u(g) * 0.447 * std::sqrt(-bend); // disc < 0 and one chord
            const glm::dvec3 d = glm::normalize(glm::dvec3(std::cos(az), std::sin(az), dz / std::sqrt(1.0 - dz * dz)));
            const glm::dvec3 o(32.0 * u(g), 32.0 * u(g), 16.0);
            falseHits += marchMesoBent<float>(grating, tq, o, d, bend).hit ? 1 : 0;
            falseHits += marchMesoBent<double>(grating, tq, o, d, bend).hit ? 1 : 0;
        }
        CHECK(falseHits == 0);
        // A chord too short for float (a ray grazing to 1e-9): a miss, with a finite t.
        const MesoHit h = marchMesoBent<float>(grating, tq, glm::dvec3(3, 4, 16), glm::normalize(glm::dvec3(1, 0, -1e-9)), -0.05);
        CHECK_FALSE(h.hit);
        CHECK(std::isfinite(h.t));
    }
    // A bend of 0 is the straight march, bit for bit; the errors.
    const MesoMaps maps = buildMesoMaps(mesoFunctionField("grating", 32, 16), mesoMapOptionsFor(MesoTechnique{}, true, ConeSet{4, 1, false, false}));
    const glm::dvec3 o(3.3, 7.1, 16.0), d = glm::normalize(glm::dvec3(0.7, 0.2, -0.3));
    checkUnbentIsStraight(maps, MesoTechnique{}, o, d);
    CHECK_THROWS_WITH(marchMesoBent<float>(maps, MesoTechnique{}, o, -d, 0.0), Contains("must enter at the top"));
    CHECK_THROWS_WITH(marchMesoBent<float>(maps, MesoTechnique{}, o, d, std::nan("")), Contains("finite bend"));
    const MesoMaps noShadow = buildMesoMaps(mesoFunctionField("grating", 16, 8), mesoMapOptionsFor(MesoTechnique{}, false, ConeSet{4, 1, false, false}));
    CHECK_THROWS_WITH(marchMesoBent<float>(noShadow, MesoTechnique{}, glm::dvec3(1, 1, 8), d, -0.01), Contains("needs shadow cones"));
}

TEST_CASE("relief mapping and POM along a bent ray find its first crossing of the height field", "[meso][frame][silhouette]") {
    // The same walk as the DDM's test above. Relief mapping and POM sample the bent ray itself
    // (no chords) in equal steps dt of its parameter, as many as make no step longer than the
    // straight ray's (the straight ray to the floor over `linear`), at least `linear` and at most
    // 4 linear (the rule of kern::dmMesoMarchHeightBent, computed here on its own), so their
    // bound is the linear search's: a crossing of the surface is found in the step where a
    // sample first lies at or below it. Between two samples above it the ray can dip below the surface by at most
    // Lip dt / 2, Lip the rate at which "how far below" changes along it (the field's steepest
    // step times the horizontal speed, |d.z| + 2 |bend| t vertically). So the hit lies between
    // the walk's first point within Lip dt / 2 of the surface, less one step, and its first
    // point Lip dt / 2 below it, plus one step; a ray bent back up that never comes within
    // Lip dt / 2 of the surface misses, and one that dips that far below before it leaves hits.
    for (const char* function : {"grating", "waves"}) {
        const MesoHeightField field = mesoFunctionField(function, 32, 16);
        const MesoMaps maps = buildMesoMaps(field, mesoMapOptionsFor(MesoTechnique{MesoMethod::Relief}, false));
        REQUIRE(maps.ddm.grid.empty()); // relief mapping reads heights only
        const double L = field.layers, steep = steepestStep(field);
        std::mt19937 g(11);
        std::uniform_real_distribution<double> u(0.0, 1.0);
        for (const MesoMethod method : {MesoMethod::Relief, MesoMethod::Pom}) {
            MesoTechnique tq;
            tq.method = method;
            tq.linear = 256;
            tq.binary = 8;
            int hits = 0, misses = 0, bentUp = 0, straight = 0, longer = 0;
            for (int k = 0; k < 1500; ++k) {
                const double elev = 0.1 + 1.3 * u(g), az = 6.283185307179586 * u(g);
                const glm::dvec3 d(std::cos(elev) * std::cos(az), std::cos(elev) * std::sin(az), -std::sin(elev));
                const glm::dvec3 o(64.0 * u(g) - 16.0, 64.0 * u(g) - 16.0, L);
                const MesoBend bend(k % 10 == 0 ? 0.0 : (k % 2 == 0 ? -1.0 : 1.0) * std::exp(-9.0 + 7.0 * u(g)), k % 3 == 1 ? -0.5 * u(g) / L : 0.0);
                const BentEnd end = bentEnd(L, d, bend);
                const bool endsAtTop = end.atTop;
                const double tEnd = end.tEnd, straightStep = (-L / d.z) / tq.linear;
                const int steps = bend.bend == 0 ? tq.linear : std::max(tq.linear, int(std::min(std::ceil(tEnd / straightStep), 4.0 * tq.linear)));
                const double dt = (bend.bend == 0 ? -L / d.z : tEnd) / steps;
                longer += steps > tq.linear ? 1 : 0;
                // (the curve's vertical speed: the depth rate times |F'|)
                const double lip = steep + end.rate * (std::abs(d.z) + 2.0 * std::abs(bend.bend) * (tEnd + dt));
                const double slack = 0.5 * lip * dt, walkSlack = lip / 64.0; // (lip: the field's step and the ray's vertical speed)
                const BentWalk w = walkBentRay(field, o, d, bend, slack + walkSlack, slack);
                glm::dvec3 slab;
                const MesoHit h = marchMesoBent<double>(maps, tq, o, d, bend, &slab);
                INFO(function << (method == MesoMethod::Pom ? " POM" : " relief") << " k " << k << " bend " << bend.bend << " curve " << bend.curve << " hit " << h.hit << " t "
                              << h.t << " n " << h.iterations << " near " << w.tNear << " deep " << w.tDeep << " dt " << dt);
                bentUp += endsAtTop ? 1 : 0;
                straight += bend.bend == 0 ? 1 : 0;
                // Samples: at most `steps` (+1 for POM's first) + binary for relief; a ray that
                // misses took every step, and nothing else.
                const int first = method == MesoMethod::Pom ? 1 : 0;
                CHECK(h.iterations <= steps + first + (method == MesoMethod::Relief ? tq.binary : 0));
                if (w.tNear < 0) {
                    CHECK_FALSE(h.hit);
                    CHECK(h.iterations == steps + first);
                    ++misses;
                    continue;
                }
                if (w.tDeep < 0) continue; // grazes the surface within the bound: either answer
                REQUIRE(h.hit);
                ++hits;
                CHECK(h.t >= w.tNear - dt - 1.0 / 64.0);
                CHECK(h.t <= w.tDeep + dt + 1.0 / 64.0);
                // The slab point is the curve's at t (no chords).
                const glm::dvec3 p = kern::dmBentPoint(o, d, bend.bend, bend.curve, h.t);
                CHECK(glm::length(slab - p) <= 1e-12 * (1.0 + h.t));
            }
            INFO(function << ": " << hits << " hits, " << misses << " misses, " << bentUp << " rays bent back up, " << straight << " straight, "
                          << longer << " longer than the straight ray");
            CHECK(hits > 600);
            CHECK(longer > 100);
            CHECK(misses > 30);
            CHECK(bentUp > 100);
        }
        // Relief mapping's bisections run on the bent ray too: with 8 coarse steps and 24
        // bisections the hit's bracket is dt / 2^24 wide, and the ray's point there lies on
        // the surface to Lip times that (a sign change of "how far below", which is continuous).
        MesoTechnique fine;
        fine.method = MesoMethod::Relief;
        fine.linear = 8;
        fine.binary = 24;
        int onSurface = 0;
        for (int k = 0; k < 500; ++k) {
            const double elev = 0.1 + 1.3 * u(g), az = 6.283185307179586 * u(g);
            const glm::dvec3 d(std::cos(elev) * std::cos(az), std::cos(elev) * std::sin(az), -std::sin(elev));
            const glm::dvec3 o(64.0 * u(g) - 16.0, 64.0 * u(g) - 16.0, L);
            const MesoBend bend((k % 2 == 0 ? -1.0 : 1.0) * std::exp(-7.0 + 5.0 * u(g)), k % 3 == 1 ? -0.5 * u(g) / L : 0.0);
            const BentEnd end = bentEnd(L, d, bend);
            const double tEnd = end.tEnd;
            const MesoHit h = marchMesoBent<double>(maps, fine, o, d, bend);
            if (!h.hit) continue;
            const double lip = steep + end.rate * (std::abs(d.z) + 2.0 * std::abs(bend.bend) * 2.0 * tEnd);
            INFO(function << " fine k " << k << " bend " << bend.bend << " t " << h.t << " below " << bentBelow(field, o, d, bend, h.t));
            CHECK(std::abs(bentBelow(field, o, d, bend, h.t)) <= lip * (tEnd / fine.linear) / 16777216.0 + 1e-9);
            ++onSurface;
        }
        CHECK(onSurface > 300);
    }
    // A bend of 0 is the straight march, bit for bit, at both precisions; POM and relief differ.
    const MesoMaps maps = buildMesoMaps(mesoFunctionField("waves", 32, 16), mesoMapOptionsFor(MesoTechnique{MesoMethod::Pom}, false));
    const glm::dvec3 o(3.3, 7.1, 16.0), d = glm::normalize(glm::dvec3(0.7, 0.2, -0.3));
    for (const MesoMethod method : {MesoMethod::Relief, MesoMethod::Pom}) {
        MesoTechnique tq;
        tq.method = method;
        checkUnbentIsStraight(maps, tq, o, d);
        // Bad rays: off the top, upward, a bend that is not finite, no linear step.
        CHECK_THROWS_WITH(marchMesoBent<float>(maps, tq, o - glm::dvec3(0, 0, 1), d, 0.01), Contains("must enter at the top"));
        CHECK_THROWS_WITH(marchMesoBent<float>(maps, tq, o, -d, 0.01), Contains("view rays go down"));
        CHECK_THROWS_WITH(marchMesoBent<float>(maps, tq, o, d, std::numeric_limits<double>::infinity()), Contains("finite bend"));
        tq.linear = 0;
        CHECK_THROWS_WITH(marchMesoBent<float>(maps, tq, o, d, 0.01), Contains("0 linear steps, not in [1, 1024]"));
    }
}

TEST_CASE("the distance map along a bent ray converges on the bent ray's crossing and never passes it", "[meso][frame][silhouette]") {
    // A flat field at h = 5.25: Donnelly's signed distance is z - h exactly at every sample (the
    // layers' centres) and trilinear interpolation keeps it exact in between, so sphere tracing
    // along the bent ray (kern::dmBentPoint; with curve 0 the parabola o + t d - bend t^2 z;
    // kern::dmMesoMarchDistanceBent) must never
    // take the point below the plane (each step moves it no farther than the distance read,
    // whatever the bend) and must converge on the ray's first crossing of z = h, where the
    // quadric's level bend t^2 - d.z t is that depth's, (L - h) + curve (L - h)^2 / 2 (its
    // smaller root); a convex ray that turns up before the plane
    // rises back through the top: a miss.
    const double h = 5.25;
    const MesoHeightField field = mesoHeightField(32, 32, 16, std::vector<float>(32 * 32, static_cast<float>(h)));
    MesoMapOptions mo;
    mo.ddm = mo.quadrics = false;
    const MesoMaps maps = buildMesoMaps(field, mo);
    MesoTechnique tq;
    tq.method = MesoMethod::DistanceMap;
    tq.iterations = 4096;
    tq.eps = 1e-10;
    const double L = field.layers;
    std::mt19937 g(3);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    int hits = 0, misses = 0, steep = 0;
    double worst = 0;
    for (int k = 0; k < 2000; ++k) {
        const double elev = 0.1 + 1.45 * u(g), az = 6.283185307179586 * u(g);
        const glm::dvec3 d(std::cos(elev) * std::cos(az), std::cos(elev) * std::sin(az), -std::sin(elev));
        const glm::dvec3 o(64.0 * u(g) - 16.0, 64.0 * u(g) - 16.0, L);
        // Every third ray's depth follows a convex curvature (MesoBend::curve, kern::dmBentPoint).
        const double bend = k % 10 == 0 ? 0.0 : (k % 2 == 0 ? -1.0 : 1.0) * std::exp(-8.0 + 7.0 * u(g)), curve = k % 3 == 1 ? -0.5 * u(g) / L : 0.0;
        // The crossing of z = h, depth L - h: the quadric's level there c + curve c^2 / 2, and the
        // smaller positive root of bend t^2 - d.z t = that.
        const double c = L - h, level = c + 0.5 * curve * c * c, disc = d.z * d.z + 4.0 * bend * level;
        const double tCross = bend == 0 ? c / -d.z : disc >= 0 ? 2.0 * level / (std::sqrt(disc) - d.z) : -1.0;
        // How fast the point falls at the crossing against the step's bound on its speed: above
        // 1, a step of the distance itself (the straight ray's rule) would pass the plane.
        steep += tCross > 0 && std::abs(d.z - 2.0 * bend * tCross) > 1.0 ? 1 : 0;
        glm::dvec3 slab;
        const MesoHit r = marchMesoBent<double>(maps, tq, o, d, MesoBend(bend, curve), &slab);
        INFO("k " << k << " d.z " << d.z << " bend " << bend << " curve " << curve << ": hit " << r.hit << " t " << r.t << " (" << r.iterations << " it), crossing " << tCross);
        const glm::dvec3 p = kern::dmBentPoint(o, d, bend, curve, r.t);
        CHECK(glm::length(slab - p) <= 1e-12 * (1.0 + r.t)); // the slab point is the curve's
        if (tCross < 0) {
            CHECK_FALSE(r.hit);
            CHECK(slab.z > L); // it left through the top
            ++misses;
            continue;
        }
        REQUIRE(r.hit);
        ++hits;
        CHECK(slab.z >= h - 1e-9 * L); // never below the plane
        CHECK(slab.z - h <= 1e-9);     // converged: within eps of it
        CHECK(r.t <= tCross + 1e-9 * (1.0 + tCross));
        worst = std::max(worst, std::abs(r.t - tCross));
    }
    INFO(hits << " hits, " << misses << " misses, " << steep << " falling faster than the step's bound, worst |t - crossing| " << worst);
    CHECK(hits > 1000);
    CHECK(misses > 50);
    CHECK(steep > 100);
    // A bend of 0 is the straight march, bit for bit, at both precisions; the errors.
    const MesoMaps grating = buildMesoMaps(mesoFunctionField("grating", 32, 16), mesoMapOptionsFor(MesoTechnique{MesoMethod::DistanceMap}, false));
    const glm::dvec3 o(3.3, 7.1, 16.0), d = glm::normalize(glm::dvec3(0.7, 0.2, -0.3));
    for (const double eps : {-1.0, 0.02}) {
        MesoTechnique dm;
        dm.method = MesoMethod::DistanceMap;
        dm.iterations = 32;
        dm.eps = eps;
        checkUnbentIsStraight(grating, dm, o, d);
    }
    CHECK_THROWS_WITH(marchMesoBent<float>(grating, tq, o - glm::dvec3(0, 0, 1), d, 0.01), Contains("must enter at the top"));
    CHECK_THROWS_WITH(marchMesoBent<float>(grating, tq, o, -d, 0.01), Contains("must enter at the top"));
    CHECK_THROWS_WITH(marchMesoBent<float>(grating, tq, o, d, std::nan("")), Contains("finite bend"));
    const MesoMaps noDistance = buildMesoMaps(mesoFunctionField("grating", 16, 8), mesoMapOptionsFor(MesoTechnique{}, false));
    CHECK_THROWS_WITH(marchMesoBent<float>(noDistance, tq, glm::dvec3(1, 1, 8), d, 0.01), Contains("distance map was not built"));
    CHECK_THROWS_WITH(marchMeso<float>(noDistance, tq, glm::dvec3(1, 1, 8), d), Contains("distance map was not built"));
}

TEST_CASE("a frame mesh's shape is its surface's second fundamental form in the texture's coordinates", "[meso][frame][silhouette]") {
    // Face placement with repeat (2, 3): (s, t) = (2 u, 3 v), so n . P_ss = n . f_uu / 4 and so
    // on, against OpenSubdiv's second derivatives of the limit surface (no displacement).
    const Built b(dmtest::shape("catmark_torus"), 3.0);
    FrameMeshOptions fo{FramePlacement::Face, {2.0, 3.0}, NormalMode::Accurate};
    CHECK_FALSE(buildFrameMesh(b.surface, b.tess, nullptr, fo).shaped);
    fo.shape = true;
    const FrameMesh fm = buildFrameMesh(b.surface, b.tess, nullptr, fo);
    CHECK(fm.shaped);
    double worst = 0, scale = 0, worstK = 0, scaleK = 0;
    for (std::size_t i = 0; i < fm.corners.size(); i += 7) {
        const glm::dvec2 p = b.tess.triangleUVs[i / 3][i % 3];
        const BaseSample<double> s = b.base.evaluate<double>(b.tess.triangleFaces[i / 3], p.x, p.y, true);
        const glm::dvec3 n = glm::normalize(glm::cross(s.du, s.dv));
        const glm::dvec3 want(glm::dot(n, s.duu) / 4.0, glm::dot(n, s.duv) / 6.0, glm::dot(n, s.dvv) / 9.0);
        worst = std::max(worst, glm::length(glm::dvec3(fm.corners[i].shape) - want));
        scale = std::max(scale, glm::length(want));
        // The most convex principal curvature: the least eigenvalue of G^-1 II in (u, v).
        const glm::dmat2 gm(glm::dot(s.du, s.du), glm::dot(s.du, s.dv), glm::dot(s.du, s.dv), glm::dot(s.dv, s.dv));
        const glm::dmat2 ii(glm::dot(n, s.duu), glm::dot(n, s.duv), glm::dot(n, s.duv), glm::dot(n, s.dvv));
        const glm::dmat2 so = glm::inverse(gm) * ii;
        const double half = 0.5 * (so[0][0] + so[1][1]);
        const double k1 = half - std::sqrt(std::max(half * half - glm::determinant(so), 0.0));
        worstK = std::max(worstK, std::abs(fm.corners[i].shape.w - std::min(k1, 0.0)));
        scaleK = std::max(scaleK, std::abs(k1));
    }
    INFO("worst " << worst << " of " << scale << ", principal curvature " << worstK << " of " << scaleK);
    // Differences of the normal with h = 1e-4 (one-sided at the face's edges: O(h) there, the
    // normal's second derivative times 1e-4) against exact second derivatives.
    CHECK(worst < 1e-3 * scale);
    CHECK(worstK < 1e-3 * scaleK);
    // A torus is convex on its outside: somewhere both directions are negative.
    CHECK(std::any_of(fm.corners.begin(), fm.corners.end(), [](const FrameVertex& v) { return v.shape.x < 0 && v.shape.z < 0; }));
}

TEST_CASE("principal curvatures do not depend on the chart: Spot by its UVs and per face", "[meso][frame][silhouette]") {
    // Through a sheared, rotated UV chart (M^-T II M^-1 with G from pS, pT) and through the
    // face's own (u, v): the shape operator's eigenvalues are the surface's, the same at every
    // corner (the same tessellation), to the differences' error.
    const Built b(dmtest::shape("spot_control_mesh"), 2.0);
    const UvMap uv(b.mesh);
    FrameMeshOptions byUv{FramePlacement::Uv, {8.0, 8.0}, NormalMode::Accurate}, byFace{FramePlacement::Face, {3.0, 5.0}, NormalMode::Accurate};
    byUv.shape = byFace.shape = true;
    const FrameMesh a = buildFrameMesh(b.surface, b.tess, &uv, byUv), c = buildFrameMesh(b.surface, b.tess, nullptr, byFace);
    REQUIRE(a.corners.size() == c.corners.size());
    std::vector<double> diff;
    for (std::size_t i = 0; i < a.corners.size(); ++i) {
        const glm::dvec2 ka = principalCurvatures(a.corners[i]), kc = principalCurvatures(c.corners[i]);
        diff.push_back(glm::length(ka - kc) / (1.0 + glm::length(kc)));
        CHECK(a.corners[i].shape.w == std::min(ka.x, 0.0));
    }
    std::sort(diff.begin(), diff.end());
    INFO("median " << diff[diff.size() / 2] << ", 99.9th percentile " << diff[diff.size() * 999 / 1000] << ", worst " << diff.back());
    // Both take the same differences in the face's (u, v) and differ in the chart they go
    // through: rounding (6e-11 at worst here); a corner nudged off a singular UV chart would be
    // evaluated 1e-3 away in one of them (none on Spot).
    CHECK(diff[diff.size() * 999 / 1000] < 1e-10);
    CHECK(diff.back() < 1e-8);
}

TEST_CASE("frame meshes of hard shapes: creases, boundaries, poles, N-gons", "[meso][frame]") {
    std::vector<std::string> shapes = {"catmark_cube", "catmark_pole8", "catmark_helmet", "catmark_bishop", "catmark_tent_creases0", "catmark_xord_boundary",
                                       "catmark_dart_edgecorner", "catmark_cube_creases0", "catmark_pyramid", "catmark_gregory_test2",
                                       "catmark_toroidal_tet", "catmark_quadstrips", "catmark_edgecorner", "catmark_flap", "catmark_hole_test1"};
    std::vector<std::string> paths;
    for (const std::string& s : shapes) paths.push_back(dmtest::dataPath(s + ".obj"));
#ifdef DISPMAP_SHARED_TESTDATA
    // Every OpenSubdiv regression shape this project reads (the rest are refused as
    // ArgumentError / MeshError by the mesh reader, tested elsewhere).
    for (const auto& e : std::filesystem::directory_iterator(std::string(DISPMAP_SHARED_TESTDATA) + "/catmull-clark/shapes"))
        if (e.path().extension() == ".obj") paths.push_back(e.path().string());
#endif
    int built = 0, withUv = 0;
    for (const std::string& path : paths) {
        std::optional<ControlMesh> mesh;
        try {
            mesh.emplace(ControlMesh::fromObjFile(path));
        } catch (const Error&) {
            continue; // non-manifold and other shapes the reader refuses (MeshError, ArgumentError)
        }
        INFO(path);
        std::optional<Built> b;
        try {
            b.emplace(std::move(*mesh), 2.0, 0.01);
        } catch (const Error&) {
            continue; // e.g. tiles the builder refuses; not this test's subject
        }
        const FrameMesh face = buildFrameMesh(b->surface, b->tess, nullptr, {FramePlacement::Face, {1.0, 1.0}, NormalMode::Accurate});
        checkSane(face, b->tess);
        ++built;
        if (b->mesh.hasUVs()) {
            const UvMap uv(b->mesh);
            try {
                const FrameMesh m = buildFrameMesh(b->surface, b->tess, &uv, {FramePlacement::Uv, {1.0, 1.0}, NormalMode::Accurate});
                checkSane(m, b->tess);
                ++withUv;
            } catch (const ArgumentError& e) {
                // Regression shapes carry placeholder UVs (all corners of a face on one point):
                // the clear refusal is the expected outcome there.
                CHECK_THAT(e.what(), Contains("is singular (a degenerate UV chart there)"));
            }
        }
    }
    INFO(built << " shapes, " << withUv << " with usable UVs");
    CHECK(built >= 12);
    // tests/data's cube has UVs; OpenSubdiv's shapes: 47 of 52 had usable ones when written.
#ifdef DISPMAP_SHARED_TESTDATA
    CHECK(withUv >= 40);
#else
    CHECK(withUv >= 1);
#endif
}

TEST_CASE("bad frame-mesh inputs are clear errors", "[meso][frame][inputs]") {
    const Built b(dmtest::shape("catmark_torus"), 2.0);
    const UvMap uv(b.mesh);
    CHECK_THROWS_WITH(buildFrameMesh(b.surface, b.tess, nullptr, {}), Contains("UV placement needs the mesh's texture coordinates"));
    for (const double r : {0.0, -1.0, std::nan(""), 1e5, std::numeric_limits<double>::infinity()})
        CHECK_THROWS_WITH(buildFrameMesh(b.surface, b.tess, &uv, {FramePlacement::Uv, {1.0, r}, NormalMode::Accurate}),
                          Contains("is not in (0, 1e4] tiles"));
    const ControlMesh grid = ControlMesh::fromObjText(dmtest::gridObj(3, 2), "grid");
    const UvMap other(grid);
    CHECK_THROWS_WITH(buildFrameMesh(b.surface, b.tess, &other, {}), Contains("the UV map has 6 ptex faces"));
    // UVs collapsed to one point: no chart to place tiles by.
    std::string flat = dmtest::gridObj(2, 2);
    for (std::size_t p = flat.find("vt "); p != std::string::npos; p = flat.find("vt ", p + 1)) {
        const std::size_t e = flat.find('\n', p);
        flat.replace(p, e - p, "vt 0.5 0.5");
    }
    const Built c(ControlMesh::fromObjText(flat, "flat-uv grid"), 2.0);
    const UvMap cuv(c.mesh);
    CHECK_THROWS_WITH(buildFrameMesh(c.surface, c.tess, &cuv, {}), Contains("is singular (a degenerate UV chart there)"));
    // The same mesh placed per face has frames everywhere.
    CHECK(buildFrameMesh(c.surface, c.tess, nullptr, {FramePlacement::Face, {1.0, 1.0}, NormalMode::Accurate}).triangleCount() ==
          c.tess.triangleCount());
}

// --- Scenes ---------------------------------------------------------------------------------
MesoSceneDesc parse(const std::string& json) {
    return parseMesoScene(nlohmann::json::parse(json), "s.json", dmtest::dataPath("scenes"));
}

TEST_CASE("a mesostructure scene's base surface", "[meso][frame][scene]") {
    SECTION("the Spot scene of tests/data") {
        const std::string path = dmtest::dataPath("scenes/meso_spot_grating.json");
        const MesoSceneDesc s = parseMesoScene(loadSceneJson(path), path, dmtest::dataPath("scenes"));
        REQUIRE(s.base);
        CHECK(s.placement.repeat == glm::dvec2(8.0));
        CHECK(s.up == glm::dvec3(0, 1, 0));
        const auto base = buildMesoSceneBase(s);
        REQUIRE(base);
        // 160 quads at 8 x 8 x 2 triangles and 92 N-gon sub-faces at half the factor (4 x 4 x 2).
        CHECK(base->triangleCount() == 160 * 128 + 92 * 32);
    }
    SECTION("no base: the plane") {
        CHECK_FALSE(buildMesoSceneBase(parse(R"({"mesostructure": {}})")));
    }
    SECTION("face placement on a mesh without UVs, a camera anywhere") {
        const MesoSceneDesc s = parse(R"({"mesostructure": {"size": 16, "layers": 8},
            "base": {"mesh": "builtin:torus", "placement": "face", "repeat": [2, 1], "tessellation": 2, "isolation": 3},
            "camera": {"eye": [0, 0, -5], "up": [0, 1, 0]}, "effects": {"shadows": true}, "light": [0, 0, -1]})");
        const auto base = buildMesoSceneBase(s);
        REQUIRE(base);
        CHECK(base->triangleCount() > 0);
        CHECK(s.base->gregoryEndCaps);
    }
    SECTION("B-spline end caps on the base") {
        const MesoSceneDesc s = parse(R"({"mesostructure": {"size": 16, "layers": 8},
            "base": {"mesh": "builtin:box", "placement": "face", "tessellation": 2, "endCaps": "bspline"},
            "camera": {"eye": [0, 0, -5], "up": [0, 1, 0]}})");
        CHECK_FALSE(s.base->gregoryEndCaps);
        const auto base = buildMesoSceneBase(s);
        REQUIRE(base);
        CHECK(base->triangleCount() > 0);
    }
    SECTION("silhouettes: the base's frames carry its curvature, only when asked") {
        const std::string scene = R"({"mesostructure": {"size": 16, "layers": 8},
            "base": {"mesh": "builtin:torus", "placement": "face", "tessellation": 2, "isolation": 3},
            "camera": {"eye": [0, 0, -5], "up": [0, 1, 0]})";
        const auto plain = buildMesoSceneBase(parse(scene + "}"));
        const MesoSceneDesc s = parse(scene + R"(, "effects": {"silhouettes": true}})");
        CHECK(s.silhouettes);
        const auto shaped = buildMesoSceneBase(s);
        REQUIRE((plain && shaped));
        CHECK_FALSE(plain->shaped);
        CHECK(shaped->shaped);
        CHECK(std::all_of(plain->corners.begin(), plain->corners.end(), [](const FrameVertex& v) { return v.shape == glm::dvec4(0.0); }));
        // The torus is convex somewhere, and every corner's most convex curvature is <= 0.
        CHECK(std::any_of(shaped->corners.begin(), shaped->corners.end(), [](const FrameVertex& v) { return v.shape.w < 0; }));
        CHECK(std::all_of(shaped->corners.begin(), shaped->corners.end(), [](const FrameVertex& v) { return v.shape.w <= 0; }));
        // The torus's inner saddle is concave around the ring: a slab deeper than that radius
        // (about the hole's) meets itself there, a thin one nowhere.
        CHECK(foldedCorners(*shaped, 1e-3) == 0);
        CHECK(foldedCorners(*shaped, 100.0) > 0);
        CHECK(foldedCorners(*shaped, 100.0) < shaped->corners.size());
        CHECK(foldedCorners(*plain, 100.0) == 0);
        CHECK_THROWS_WITH(parse(R"({"mesostructure": {}, "effects": {"silhouettes": true}})"),
                          Contains("'effects.silhouettes' needs a 'base'"));
        CHECK_THROWS_WITH(parse(scene + R"(, "effects": {"silhouettes": 1}})"), Contains("'effects.silhouettes' must be true or false"));
        // Bent rays: the base's curvature too, and the DDM's shadow cones (a ray bent back up).
        const MesoSceneDesc bent = parse(scene + R"(, "effects": {"bentRays": true}})");
        CHECK((bent.bentRays && !bent.silhouettes && bent.placement.shape));
        CHECK(buildMesoSceneMaps(bent).ddm.cones.shadow);
        CHECK_FALSE(buildMesoSceneMaps(parse(scene + "}")).ddm.cones.shadow);
        CHECK_THROWS_WITH(parse(R"({"mesostructure": {}, "effects": {"bentRays": true}})"), Contains("'effects.bentRays' needs a 'base'"));
        // The distance map bends its rays too, and needs no DDM for them.
        const MesoSceneDesc bentDistance = parse(scene + R"(, "effects": {"bentRays": true, "technique": "distance_map"}})");
        CHECK(bentDistance.bentRays);
        CHECK(buildMesoSceneMaps(bentDistance).ddm.grid.empty());
        // Relief mapping and POM bend their rays too, and read only heights: no DDM is built for them.
        const MesoSceneDesc bentPom = parse(scene + R"(, "effects": {"bentRays": true, "technique": "pom"}})");
        CHECK((bentPom.bentRays && bentPom.placement.shape));
        CHECK(buildMesoSceneMaps(bentPom).ddm.grid.empty());
        // A solid bends its rays as the DDM of a height field does: with shadow cones.
        const MesoSceneDesc bentSolid = parse(R"({"mesostructure": {"mesh": "../chainmail.obj", "size": 16, "layers": 16},
                                                  "base": {"mesh": "builtin:torus", "placement": "face"},
                                                  "camera": {"eye": [0, 0, -5], "up": [0, 1, 0]}, "effects": {"bentRays": true}})");
        const MesoMaps solidMaps = buildMesoSceneMaps(bentSolid);
        CHECK((bentSolid.bentRays && solidMaps.isSolid() && solidMaps.ddm.cones.shadow));
    }
    SECTION("bad base objects") {
        const auto bad = [](const std::string& base, const std::string& why) {
            INFO(base);
            CHECK_THROWS_WITH(parse(R"({"mesostructure": {}, "base": )" + base + "}"), Contains(why));
        };
        bad(R"({"placement": "uv"})", "'base.mesh' is missing");
        bad(R"({"mesh": "builtin:torus", "endCaps": "loop"})", "endCaps: unknown value 'loop' (gregory, bspline)");
        bad(R"({"mesh": "builtin:torus", "colour": 1})", "unknown key 'base.colour'");
        bad(R"({"mesh": "builtin:torus", "placement": "planar"})", "unknown 'base.placement' 'planar' (uv, face)");
        bad(R"({"mesh": "builtin:torus", "repeat": [1]})", "'base.repeat' must be a number or [s, t]");
        bad(R"({"mesh": "builtin:torus", "repeat": -2})", "'base.repeat' must be in (0, 1e4] tiles");
        bad(R"({"mesh": "builtin:torus", "tessellation": 65})", "'base.tessellation' must be in 1..64");
        bad(R"({"mesh": "builtin:torus", "uv": "smoth"})", "unknown 'base.uv' 'smoth'");
        bad(R"({"mesh": "builtin:cone"})", "unknown built-in mesh 'cone'");
        bad(R"({"mesh": "builtin:torus", "displacement": {"scale": "x"}})", "displacement.scale");
        CHECK_THROWS_WITH(parse(R"({"mesostructure": {}, "camera": {"eye": [0, 0, 2], "up": [0, 0, 3]}})"),
                          Contains("'camera.up' is zero or parallel to the view direction"));
        CHECK_THROWS_WITH(parse(R"({"mesostructure": {}, "checker": -1})"), Contains("'checker' must be in [0, 1e6] voxels"));
        // Without a base the plane's rules stay.
        CHECK_THROWS_WITH(parse(R"({"mesostructure": {}, "camera": {"eye": [0, 1, -1]}})"), Contains("must be above the plane z = 0"));
        CHECK_THROWS_WITH(parse(R"({"mesostructure": {}, "camera": {"up": [0, 1, 0]}})"), Contains("'camera.up' must be +z over the plane"));
    }
    SECTION("UV placement on a mesh without UVs: a clear error when the base is built") {
        const MesoSceneDesc s = parse(R"({"mesostructure": {}, "base": {"mesh": "builtin:torus", "tessellation": 2}})");
        CHECK_THROWS_WITH(buildMesoSceneBase(s), Contains("s.json: 'base.placement' \"uv\" needs texture coordinates and the mesh 'builtin:torus' has none"));
    }
    SECTION("a base mesh file that is missing") {
        const MesoSceneDesc s = parse(R"({"mesostructure": {}, "base": {"mesh": "no_such_cage.obj"}})");
        CHECK_THROWS_AS(buildMesoSceneBase(s), FileError);
    }
}

TEST_CASE("groupFrameMesh orders the triangles by group, stably, and counts them", "[meso][frame]") {
    const Built b(dmtest::shape("catmark_torus"), 2.0);
    const UvMap uv(b.mesh);
    const FrameMesh whole = buildFrameMesh(b.surface, b.tess, &uv, {});
    REQUIRE(std::ranges::equal(whole.faces, b.tess.triangleFaces));
    CHECK(whole.groups.empty());
    // Faces by parity into groups 2 and 0; group 1 gets none.
    std::vector<int> groupOf(static_cast<std::size_t>(b.base.faceCount()));
    for (std::size_t f = 0; f < groupOf.size(); ++f) groupOf[f] = f % 2 ? 0 : 2;
    FrameMesh m = whole;
    const std::vector<int> counts = groupFrameMesh(m, groupOf, 3);
    CHECK(m.groups == counts);
    REQUIRE(counts.size() == 3);
    CHECK(counts[1] == 0);
    CHECK(counts[0] + counts[2] == whole.triangleCount());
    // Each group's triangles are the input's of that group, in the input's order, corners whole.
    std::size_t at = 0;
    for (int g : {0, 1, 2})
        for (std::size_t t = 0; t < whole.faces.size(); ++t)
            if (groupOf[static_cast<std::size_t>(whole.faces[t])] == g) {
                CHECK(m.faces[at] == whole.faces[t]);
                for (std::size_t c = 0; c < 3; ++c) CHECK(m.corners[3 * at + c].position == whole.corners[3 * t + c].position);
                CHECK(m.corners[3 * at + 2].tex == whole.corners[3 * t + 2].tex);
                ++at;
            }
    CHECK(at == whole.faces.size());
    // Bad inputs.
    FrameMesh bad = whole;
    CHECK_THROWS_WITH(groupFrameMesh(bad, groupOf, 2), Contains("is in group 2, not in 0 .. 1"));
    CHECK_THROWS_WITH(groupFrameMesh(bad, {0, 0}, 1), Contains("beyond the 2 faces grouped"));
    CHECK_THROWS_WITH(groupFrameMesh(bad, groupOf, 0), Contains("0 groups"));
    bad.faces.pop_back();
    CHECK_THROWS_WITH(groupFrameMesh(bad, groupOf, 3), Contains("triangle faces for"));
}

TEST_CASE("several mesostructures on a base, one an OBJ material", "[meso][frame][scene]") {
    const std::string mesh = dmtest::dataPath("spot_materials.obj");
    const std::string head = R"({"base": {"mesh": ")" + mesh + R"(", "isolation": 2, "tessellation": 2}, "mesostructure": )";
    SECTION("three materials: each triangle lies under its face's material") {
        const MesoSceneDesc s = parse(head + R"([{"material": "hide", "size": 16, "layers": 8},
            {"material": "head", "function": "waves", "size": 8, "layers": 4}, {"size": 32, "layers": 8, "cones": "isotropic"}]})");
        const std::vector<MesoSceneDesc> parts = mesoSceneParts(s);
        REQUIRE(parts.size() == 3);
        CHECK(parts[1].function == "waves");
        CHECK(parts[1].key == "mesostructure[1]");
        CHECK(parts[2].material.empty());
        CHECK(parts[2].cones.isotropic);
        CHECK(parts[0].others.empty());
        CHECK(parts[2].eye == s.eye); // the scene's keys are shared
        const auto base = buildMesoSceneBase(s);
        REQUIRE(base);
        REQUIRE(base->groups.size() == 3);
        CHECK(base->groups[0] + base->groups[1] + base->groups[2] == base->triangleCount());
        // The part of each triangle from its control face's centroid, by the rule the file's
        // materials were written with (its header), not from the materials read; the ptex faces
        // of a control face from OpenSubdiv's adjacency of sub-faces (a quad's is itself).
        const ControlMesh cage = ControlMesh::fromObjFile(mesh);
        const MeshDescription& d = cage.description();
        const Far::TopologyLevel& level = cage.base();
        std::vector<std::string> materialOfPtex(static_cast<std::size_t>(cage.ptexFaceCount()));
        for (int f = 0; f < level.GetNumFaces(); ++f) {
            glm::dvec3 c(0.0);
            const auto fv = level.GetFaceVertices(f);
            for (int k = 0; k < fv.size(); ++k) c += d.positions[static_cast<std::size_t>(fv[k])] / double(fv.size());
            const std::string m = c.z < -0.35 ? "head" : c.y < -0.45 ? "legs" : "hide";
            for (int k = 0; k < (fv.size() == 4 ? 1 : fv.size()); ++k) materialOfPtex[static_cast<std::size_t>(cage.ptex().GetFaceId(f) + k)] = m;
        }
        CHECK(std::count(materialOfPtex.begin(), materialOfPtex.end(), "") == 0);
        std::size_t t = 0;
        for (int g = 0; g < 3; ++g)
            for (int i = 0; i < base->groups[static_cast<std::size_t>(g)]; ++i, ++t) {
                const std::string& m = materialOfPtex[static_cast<std::size_t>(base->faces[t])];
                CHECK(m == (g == 0 ? "hide" : g == 1 ? "head" : "legs"));
            }
        // The same base without materials, ungrouped, has the same triangles.
        const auto one = buildMesoSceneBase(parse(head + R"({"size": 16, "layers": 8}})"));
        CHECK(one->groups.empty());
        CHECK(one->triangleCount() == base->triangleCount());
    }
    SECTION("bad arrays and materials are clear errors") {
        const auto bad = [&](const std::string& parts, const std::string& why) {
            INFO(parts);
            CHECK_THROWS_WITH(buildMesoSceneBase(parse(head + parts + "}")), Contains(why));
        };
        bad("[]", "'mesostructure' is an array of 0 mesostructures (1 .. 16)");
        bad(R"([{"material": "hide"}, {"material": "hide"}])", "'mesostructure[0]' and 'mesostructure[1]' are both on material 'hide'");
        bad(R"([{}, {"material": "head"}, {}])", "'mesostructure[0]' and 'mesostructure[2]' both lack a 'material'");
        bad(R"([{"material": ""}])", "'mesostructure[0].material' must be a material's name");
        bad(R"([{"material": 3}])", "'mesostructure[0].material' must be a material's name");
        bad(R"([{"material": "hide"}, {"material": "head", "layers": 1}])", "'mesostructure[1].layers' out of range");
        bad(R"([{"material": "hide"}, {"material": "head", "colour": 1}])", "unknown key 'mesostructure[1].colour'");
        bad(R"([{"material": "hide"}, {"material": "horns"}])", "'mesostructure[1].material' 'horns' is not a material of the mesh");
        bad(R"([{"material": "hide"}, {"material": "head"}])", "(material 'legs') lies under no mesostructure");
        bad(R"({"material": "hide"})", "lies under no mesostructure: give one that material");
        std::string many = "[";
        for (int i = 0; i < 17; ++i) many += std::string(i ? "," : "") + R"({"material": "m)" + std::to_string(i) + R"("})";
        bad(many + "]", "an array of 17 mesostructures (1 .. 16)");
        // A mesh without materials; the plane.
        CHECK_THROWS_WITH(buildMesoSceneBase(parse(R"({"base": {"mesh": "builtin:torus", "placement": "face", "tessellation": 2},
            "camera": {"eye": [0, 0, -5], "up": [0, 1, 0]}, "mesostructure": [{"material": "hide"}, {}]})")),
                          Contains("'hide' is not a material of the mesh 'torus 8x6' (it names no material: OBJ usemtl)"));
        CHECK_THROWS_WITH(parse(R"({"mesostructure": [{}]})"), Contains("'mesostructure' as an array needs a 'base'"));
        CHECK_THROWS_WITH(parse(R"({"mesostructure": {"material": "hide"}})"), Contains("'mesostructure.material' needs a 'base'"));
    }
    SECTION("each its own repeat and slab") {
        const std::string three = R"([{"material": "hide", "size": 16, "layers": 8}, {"material": "head", "size": 16, "layers": 8},
            {"material": "legs", "size": 16, "layers": 8)";
        const auto same = buildMesoSceneBase(parse(head + three + "}]}"));
        const MesoSceneDesc s = parse(head + three + R"(, "repeat": [2, 4], "slab": 0.5, "normals": "height"}]})");
        CHECK(s.others[1].slab == 0.5);
        CHECK(s.slab == 0.06);
        CHECK(s.others[1].placement.repeat == glm::dvec2(2.0, 4.0));
        const auto legs = buildMesoSceneBase(s);
        REQUIRE(legs->groups == same->groups);
        // The legs' frames at 2 and 4 tiles a UV unit instead of 1: pS halved, pT a quarter;
        // the other parts' corners unchanged, bit for bit.
        const std::size_t first = 3 * static_cast<std::size_t>(same->groups[0] + same->groups[1]);
        for (std::size_t i = 0; i < same->corners.size(); ++i) {
            const FrameVertex &a = same->corners[i], &b = legs->corners[i];
            if (i < first) {
                CHECK((a.pS == b.pS && a.tex == b.tex));
            } else {
                CHECK(glm::length(b.pS * 2.0 - a.pS) <= 1e-12 * glm::length(a.pS));
                CHECK(glm::length(b.pT * 4.0 - a.pT) <= 1e-12 * glm::length(a.pT));
            }
        }
        // A normal map made from heights takes its slope over its own triangles' tile width
        // (about half the whole mesh's here): not the map of the whole mesh's mean width.
        const MesoSceneDesc part = mesoSceneParts(s)[2];
        FrameMesh whole = *legs;
        whole.groups.clear();
        const double own = legs->meanTileWidth(first / 3, static_cast<std::size_t>(legs->groups[2]));
        INFO("the legs' tile width " << own << ", the whole mesh's " << whole.meanTileWidth());
        CHECK(own < 0.8 * whole.meanTileWidth());
        CHECK(buildMesoSceneNormals(part, legs.get())->words != buildMesoSceneNormals(part, &whole)->words);
        const auto bad = [&](const std::string& last, const std::string& why) {
            INFO(last);
            CHECK_THROWS_WITH(parse(head + three + last + "]}"), Contains(why));
        };
        bad(R"(, "repeat": 0})", "'mesostructure[2].repeat' must be in (0, 1e4] tiles");
        bad(R"(, "repeat": "x"})", "'mesostructure[2].repeat' must be a number or [s, t]");
        bad(R"(, "slab": -1})", "'mesostructure[2].slab' must be > 0");
        CHECK_THROWS_WITH(parse(R"({"mesostructure": {"repeat": 2}})"), Contains("'mesostructure.repeat' needs a 'base'"));
        // Per-face repeats given directly: one a ptex face, each in range.
        const Built b(dmtest::shape("catmark_torus"), 2.0);
        const UvMap uv(b.mesh);
        FrameMeshOptions o;
        o.faceRepeat.assign(3, glm::dvec2(1.0));
        CHECK_THROWS_WITH(buildFrameMesh(b.surface, b.tess, &uv, o), Contains("3 face repeats for " + std::to_string(b.base.faceCount()) + " ptex faces"));
        o.faceRepeat.assign(static_cast<std::size_t>(b.base.faceCount()), glm::dvec2(1.0, 0.0));
        CHECK_THROWS_WITH(buildFrameMesh(b.surface, b.tess, &uv, o), Contains("a face's repeat 0.000000 is not in (0, 1e4] tiles"));
    }
    SECTION("holes lie under none; a mesostructure must cover a face") {
        // A strip of three quads, materials a, b, a; the b face a hole.
        dmtest::TempDir dir("dispmap_materials_");
        std::string obj = "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\nv 3 1 0\n";
        obj += "usemtl a\nf 1 2 6 5\nusemtl b\nf 2 3 7 6\nusemtl a\nf 3 4 8 7\nt hole 1/0/0 1\n";
        dmtest::writeBytes((dir.path / "strip.obj").string(), std::vector<unsigned char>(obj.begin(), obj.end()));
        const auto strip = [&](const std::string& parts) {
            return parseMesoScene(nlohmann::json::parse(R"({"base": {"mesh": "strip.obj", "placement": "face", "tessellation": 2},
                "camera": {"eye": [1.5, 0.5, 3], "target": [1.5, 0.5, 0], "up": [0, 1, 0]}, "mesostructure": )" + parts + "}"),
                                  "strip.json", dir.path.string());
        };
        const auto base = buildMesoSceneBase(strip(R"([{"material": "a", "size": 16, "layers": 8}])"));
        REQUIRE(base);
        CHECK(base->groups == std::vector<int>{base->triangleCount()});
        CHECK_THROWS_WITH(buildMesoSceneBase(strip(R"([{"material": "a"}, {"material": "b"}])")),
                          Contains("'mesostructure[1]' covers no face of the mesh"));
        CHECK_THROWS_WITH(buildMesoSceneBase(strip(R"([{"material": "a"}, {}])")), Contains("'mesostructure[1]' covers no face of the mesh"));
    }
    SECTION("the scene of tests/data") {
        const std::string path = dmtest::dataPath("scenes/meso_spot_materials.json");
        const MesoSceneDesc s = parseMesoScene(loadSceneJson(path), path, dmtest::dataPath("scenes"));
        CHECK(mesoSceneParts(s).size() == 3);
        CHECK(s.others[1].material == "legs");
    }
}

} // namespace
} // namespace frame_mesh_test
