#pragma once
// Quadrics (Mehra & Kumar Eq. 1 and Appendix B): bilinear and triangular patches as
// quadrics, one per column of the height field (its bilinear patch), continuous across voxel
// faces because neighbouring patches share their corner points. GLM only.
#include "dispmap/meso/height_field.h"

namespace dispmap {

/// Q(p) = A x^2 + B y^2 + C z^2 + D xy + E yz + F zx + G x + H y + I z + J in the kernels'
/// packing: a = (A, B, C, D), b = (E, F, G, H), c = (I, J, ., .).
struct Quadric {
    glm::dvec4 a{0}, b{0}, c{0};
    double operator()(const glm::dvec3& p) const { return kern::dmQuadricValue(a, b, c, p); }
};

namespace detail {
// (alpha . X + alpha0)(beta . X + beta0) + gamma . X + gamma0, expanded.
inline Quadric productQuadric(const glm::dvec3& al, double al0, const glm::dvec3& be, double be0, const glm::dvec3& ga, double ga0) {
    Quadric q;
    q.a = {al.x * be.x, al.y * be.y, al.z * be.z, al.x * be.y + al.y * be.x};
    q.b = {al.y * be.z + al.z * be.y, al.z * be.x + al.x * be.z, al.x * be0 + al0 * be.x + ga.x, al.y * be0 + al0 * be.y + ga.y};
    q.c = {al.z * be0 + al0 * be.z + ga.z, al0 * be0 + ga0, 0, 0};
    return q;
}
// Scales q so its largest coefficient is 1 in magnitude and it grows from the patch point
// `on` towards `inside` (its gradient there: a far probe point could lie beyond the fold of
// a twisted patch's quadric).
inline Quadric normalised(Quadric q, const glm::dvec3& on, const glm::dvec3& inside) {
    double big = 0;
    for (int i = 0; i < 4; ++i) big = std::max({big, std::abs(q.a[i]), std::abs(q.b[i])});
    big = std::max({big, std::abs(q.c.x), std::abs(q.c.y)});
    if (!(big > 0) || !std::isfinite(big)) throw ArgumentError("quadric: degenerate patch (no finite coefficient)");
    const glm::dvec3 p = on;
    const glm::dvec3 grad(2 * q.a.x * p.x + q.a.w * p.y + q.b.y * p.z + q.b.z, 2 * q.a.y * p.y + q.a.w * p.x + q.b.x * p.z + q.b.w,
                          2 * q.a.z * p.z + q.b.x * p.y + q.b.y * p.x + q.c.x);
    const double s = (glm::dot(grad, inside - on) < 0 ? -1.0 : 1.0) / big;
    q.a *= s;
    q.b *= s;
    q.c.x *= s;
    q.c.y *= s;
    return q;
}
} // namespace detail

/// Appendix B: the quadric of the bilinear patch (1-u)(1-v) P1 + u(1-v) P2 + uv P3 + (1-u)v P4,
/// positive on the side of `inside` (a point off the patch, judged at the patch's centre). Derivation (the paper's appendix
/// gives only the substitution): with Y = X - P1, a = P1 + P3 - P2 - P4, b = P2 - P1,
/// c = P4 - P1, n = b x c, gu = (c x n)/|n|^2, gv = (n x b)/|n|^2, gw = n/|n|^2 and ka = gu.a,
/// kb = gv.a, kn = gw.a, the patch has gu.Y = u + ka uv, gv.Y = v + kb uv, gw.Y = kn uv, so
/// F = (gu.Y - (ka/kn) gw.Y)(kn gv.Y - kb gw.Y) - gw.Y = u (kn v) - kn uv = 0 on it. F is
/// normalised by kn (the unnormalised product form vanishes identically as the patch flattens);
/// a patch with |kn| <= 1e-12 (|ka| + |kb| + 1) is planar and becomes its plane gw.Y = 0.
/// ArgumentError when b and c are parallel (no plane).
inline Quadric bilinearPatchQuadric(const glm::dvec3& P1, const glm::dvec3& P2, const glm::dvec3& P3, const glm::dvec3& P4,
                                    const glm::dvec3& inside) {
    const glm::dvec3 a = P1 + P3 - P2 - P4, b = P2 - P1, c = P4 - P1, n = glm::cross(b, c);
    const double nn = glm::dot(n, n);
    if (!(nn > 1e-24 * glm::dot(b, b) * glm::dot(c, c)) || !std::isfinite(nn))
        throw ArgumentError("bilinearPatchQuadric: the patch's edges P2 - P1 and P4 - P1 are parallel or not finite");
    const glm::dvec3 centre = 0.25 * (P1 + P2 + P3 + P4);
    const glm::dvec3 gu = glm::cross(c, n) / nn, gv = glm::cross(n, b) / nn, gw = n / nn;
    const double ka = glm::dot(gu, a), kb = glm::dot(gv, a), kn = glm::dot(gw, a);
    if (std::abs(kn) <= 1e-12 * (std::abs(ka) + std::abs(kb) + 1))
        return detail::normalised(detail::productQuadric(glm::dvec3(0), 0, glm::dvec3(0), 0, gw, -glm::dot(gw, P1)), centre, inside);
    const glm::dvec3 al = gu - (ka / kn) * gw, be = kn * gv - kb * gw;
    return detail::normalised(detail::productQuadric(al, -glm::dot(al, P1), be, -glm::dot(be, P1), -gw, glm::dot(gw, P1)), centre,
                              inside);
}

/// Appendix B for a triangle u P1 + v P2 + (1-u-v) P3: its plane, positive on the side of `inside`.
inline Quadric triangleQuadric(const glm::dvec3& P1, const glm::dvec3& P2, const glm::dvec3& P3, const glm::dvec3& inside) {
    const glm::dvec3 n = glm::cross(P2 - P1, P3 - P1);
    if (!(glm::dot(n, n) > 0) || !std::isfinite(glm::dot(n, n))) throw ArgumentError("triangleQuadric: degenerate triangle");
    return detail::normalised(detail::productQuadric(glm::dvec3(0), 0, glm::dvec3(0), 0, n, -glm::dot(n, P1)), (P1 + P2 + P3) / 3.0,
                              inside);
}

/// One quadric per column of a height field (its bilinear patch), in the column's frame
/// (x - i, y - j, z); q[3 (j width + i) + 0..2] = (a, b, c) with c.z, c.w = the lowest and
/// highest corner height (dmVoxelQuadric). Neighbouring columns share their corner points,
/// so the surface is C0 across voxel faces.
struct ColumnQuadrics {
    int width = 0, height = 0;
    std::vector<glm::vec4> q;
    std::size_t bytes() const { return q.size() * sizeof(glm::vec4); }
};

inline ColumnQuadrics buildColumnQuadrics(const MesoHeightField& hf) {
    ColumnQuadrics out;
    out.width = hf.width;
    out.height = hf.height;
    out.q.resize(static_cast<std::size_t>(hf.width) * static_cast<std::size_t>(hf.height) * 3);
    for (int j = 0; j < hf.height; ++j)
        for (int i = 0; i < hf.width; ++i) {
            const glm::dvec4 h(hf.cell(i, j));
            const double lo = std::min(std::min(h.x, h.y), std::min(h.z, h.w)), hi = std::max(std::max(h.x, h.y), std::max(h.z, h.w));
            const Quadric Q = bilinearPatchQuadric({0, 0, h.x}, {1, 0, h.y}, {1, 1, h.z}, {0, 1, h.w}, {0.5, 0.5, lo - 1.0});
            const std::size_t at = 3 * (static_cast<std::size_t>(j) * static_cast<std::size_t>(hf.width) + static_cast<std::size_t>(i));
            out.q[at] = glm::vec4(Q.a);
            out.q[at + 1] = glm::vec4(Q.b);
            out.q[at + 2] = glm::vec4(static_cast<float>(Q.c.x), static_cast<float>(Q.c.y), static_cast<float>(lo), static_cast<float>(hi));
        }
    return out;
}

} // namespace dispmap
