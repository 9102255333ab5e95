#pragma once
// Built-in control meshes and procedural displacements: the embedded default scene of
// `dispmap demo`, the torus cages of the benchmark tables, and the meshes a scene file names
// as "builtin:<name>" (scene.h). No files needed.
#include <cmath>
#include <string>

#include "dispmap/core/error.h"
#include "dispmap/surface/mesh.h"

namespace dispmap::builtin {

/// The default cage: the box [-1, 1]^3 with two extra vertices on its top edges, so that it has
/// valence-3, -4 and -5 vertices and non-quad faces with T-junctions against their quad
/// neighbours: 7 faces (3 quads, 3 pentagons, a triangle), 21 Ptex faces.
inline ControlMesh defaultMesh() {
    static const char* obj = R"(v -1 -1 -1
v 1 -1 -1
v 1 1 -1
v -1 1 -1
v -1 -1 1
v 1 -1 1
v 1 1 1
v -1 1 1
v 0 -1 1
v 0 1 1
f 1 4 3 2
f 1 2 6 9 5
f 2 3 7 6
f 3 4 8 10 7
f 4 1 5 8
f 5 9 8
f 9 6 7 10 8
)";
    return ControlMesh::fromObjText(obj, "default scene");
}

/// The default procedural displacement ("waves"): two products of sines of 3 x 2 cycles per
/// face, phase-shifted by the face id, plus a diagonal ripple of 9 cycles; |D| <= 0.07.
inline double defaultDisplacement(int face, double u, double v) {
    const double pi = 3.14159265358979323846;
    return 0.05 * std::sin(2 * pi * 3 * u + face) * std::sin(2 * pi * 2 * v) + 0.02 * std::cos(2 * pi * 9 * (u + v));
}

/// A torus cage of n x m quads around the z axis, main radius R, tube radius r; face
/// i + n j spans angles [i, i + 1] / n turns around the main circle and [j, j + 1] / m around
/// the tube. Throws ArgumentError unless n, m >= 3 and 0 < r < R are finite.
inline ControlMesh torusCage(int n, int m, double R, double r, const std::string& name) {
    if (n < 3 || m < 3 || !std::isfinite(R) || !std::isfinite(r) || !(r > 0.0) || !(r < R))
        throw ArgumentError("torusCage: need n, m >= 3 and 0 < r < R (got n = " + std::to_string(n) +
                            ", m = " + std::to_string(m) + ", R = " + std::to_string(R) + ", r = " + std::to_string(r) + ")");
    const double tau = 6.283185307179586;
    std::string obj;
    for (int j = 0; j < m; ++j)
        for (int i = 0; i < n; ++i) {
            const double a = tau * i / n, b = tau * j / m, w = R + r * std::cos(b);
            obj += "v " + std::to_string(w * std::cos(a)) + " " + std::to_string(w * std::sin(a)) + " " +
                   std::to_string(r * std::sin(b)) + "\n";
        }
    for (int j = 0; j < m; ++j)
        for (int i = 0; i < n; ++i) {
            auto id = [&](int a, int b) { return std::to_string((b % m) * n + (a % n) + 1); };
            obj += "f " + id(i, j) + " " + id(i + 1, j) + " " + id(i + 1, j + 1) + " " + id(i, j + 1) + "\n";
        }
    return ControlMesh::fromObjText(obj, name);
}

/// The torus of the normals table: 8 x 6 quads, radii 2 and 0.6 (curvature up to 1 / 0.6).
inline ControlMesh torusMesh() { return torusCage(8, 6, 2.0, 0.6, "torus 8x6"); }

/// The torus's displacement: amplitude up to 0.12 at 3 cycles per face on one side of the
/// torus, fading to nothing on the other (the angle around the main circle is
/// (face % 8 + u) / 8 turns), so that auto normals spend the Weingarten term on one side only.
inline double torusDisplacement(int face, double u, double v) {
    const double tau = 6.283185307179586, a = tau * (face % 8 + u) / 8.0;
    const double amplitude = 0.12 * std::pow(0.5 + 0.5 * std::cos(a), 3.0);
    return amplitude * std::sin(tau * 3 * u + 0.7 * face) * std::cos(tau * 3 * v);
}

/// The OBJ text of a fan of n quads around a centre vertex (valence n; n >= 3): ring A of 2n vertices (edge and
/// face vertices alternating) on a curved, deliberately asymmetric cap. Closed: a band of
/// quads down to ring B and a second fan (valence n at both poles, valence 3 at the odd
/// ring vertices). Open: the cap alone, a boundary all round.
inline std::string fanObj(int n, bool closed) {
    std::string s;
    auto vtx = [&](double x, double y, double z) {
        s += "v " + std::to_string(x) + " " + std::to_string(y) + " " + std::to_string(z) + "\n";
    };
    const double pi = 3.141592653589793;
    vtx(0.05, -0.03, 0.6); // 1: top centre
    for (int i = 0; i < 2 * n; ++i) {
        const double a = pi * i / n, r = (i % 2 ? 1.3 : 1.0) * (1.0 + 0.15 * std::cos(a));
        vtx(r * std::cos(a), r * std::sin(a), 0.25 * std::sin(2 * a) * (i % 2 ? 0.5 : 1.0) + 0.1 * r);
    }
    auto A = [&](int i) { return 2 + ((i % (2 * n)) + 2 * n) % (2 * n); };
    if (closed) {
        for (int i = 0; i < 2 * n; ++i) {
            const double a = pi * i / n, r = (i % 2 ? 1.2 : 1.0);
            vtx(r * std::cos(a), r * std::sin(a), -0.9 - 0.1 * std::cos(a));
        }
        vtx(-0.04, 0.02, -1.5); // bottom centre
    }
    auto B = [&](int i) { return 2 + 2 * n + ((i % (2 * n)) + 2 * n) % (2 * n); };
    const int bottom = 2 + 4 * n;
    auto face = [&](int a, int b, int c, int d) {
        s += "f " + std::to_string(a) + " " + std::to_string(b) + " " + std::to_string(c) + " " + std::to_string(d) + "\n";
    };
    for (int k = 0; k < n; ++k) face(1, A(2 * k), A(2 * k + 1), A(2 * k + 2));
    if (closed) {
        for (int i = 0; i < 2 * n; ++i) face(A(i + 1), A(i), B(i), B(i + 1));
        for (int k = 0; k < n; ++k) face(bottom, B(2 * k + 2), B(2 * k + 1), B(2 * k));
    }
    return s;
}

/// The names builtinMesh accepts, for messages.
inline const char* builtinMeshNames() { return "box, torus"; }

/// A built-in mesh by name: "box" (defaultMesh) or "torus" (torusMesh). Throws ArgumentError
/// listing the known names otherwise.
inline ControlMesh builtinMesh(const std::string& name) {
    if (name == "box") return defaultMesh();
    if (name == "torus") return torusMesh();
    throw ArgumentError("unknown built-in mesh '" + name + "' (known: " + builtinMeshNames() + ")");
}

} // namespace dispmap::builtin
