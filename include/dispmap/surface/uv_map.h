#pragma once
// UvMap: the texture coordinate of a point (ptex face, u, v) of the limit surface, in the
// mesh's UV layout, and its derivatives along u and v (the footprint of a sample, for
// prefiltering).
//
// Two ways, chosen by UvInterpolation:
//  * Linear: each face's corner UVs interpolated bilinearly over the face (a non-quad's
//    sub-face: corner, edge midpoints, centroid), what dispmap always did and what
//    OpenSubdiv's FVAR_LINEAR_ALL gives;
//  * smooth rules: OpenSubdiv's face-varying subdivision of the UVs (Bfr face-varying
//    surfaces, one per base face), with the boundary and corner rule that sculpting tools
//    expose as "smooth UVs" (Sdc::Options::FVarLinearInterpolation):
//      smooth      FVAR_LINEAR_NONE           everything smooth, boundaries too
//      corners     FVAR_LINEAR_CORNERS_ONLY   UV-seam corners kept sharp
//      corners+1   FVAR_LINEAR_CORNERS_PLUS1  also junctions of 3+ charts (Blender's
//                                             "Keep Corners, Junctions")
//      corners+2   FVAR_LINEAR_CORNERS_PLUS2  also concave corners
//      boundaries  FVAR_LINEAR_BOUNDARIES     seams and boundaries linear, interior smooth
//    A map painted or baked on the smoothed UV layout lands in the wrong place under linear
//    UVs by up to the difference of the two layouts (tests/test_map_source.cpp measures it).
//  * Mesh: the rule the OBJ file names (`t facevaryinginterpolateboundary`), linear if none.
// Each face reads its own face-varying values, so faces on either side of a UV seam sample
// their own charts.
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>
#include <opensubdiv/bfr/refinerSurfaceFactory.h>
#include <opensubdiv/bfr/surface.h>

#include "dispmap/core/error.h"
#include "dispmap/core/triangle_mesh.h"
#include "dispmap/surface/mesh.h"

namespace dispmap {
namespace Bfr = OpenSubdiv::Bfr;

enum class UvInterpolation { Mesh, Linear, Smooth, CornersOnly, CornersPlus1, CornersPlus2, Boundaries };

/// The names of the rules, as the CLI and scene files spell them.
inline constexpr std::array<std::pair<std::string_view, UvInterpolation>, 7> kUvInterpolationNames{{
    {"mesh", UvInterpolation::Mesh},
    {"linear", UvInterpolation::Linear},
    {"smooth", UvInterpolation::Smooth},
    {"corners", UvInterpolation::CornersOnly},
    {"corners+1", UvInterpolation::CornersPlus1},
    {"corners+2", UvInterpolation::CornersPlus2},
    {"boundaries", UvInterpolation::Boundaries},
}};

/// The rule named `name`, or none.
inline std::optional<UvInterpolation> parseUvInterpolation(std::string_view name) {
    for (const auto& [n, r] : kUvInterpolationNames)
        if (n == name) return r;
    return std::nullopt;
}

/// "mesh, linear, smooth, ...": for error messages.
inline std::string uvInterpolationNames() {
    std::string s;
    for (const auto& [n, r] : kUvInterpolationNames) s += (s.empty() ? "" : ", ") + std::string(n);
    return s;
}

/// A texture coordinate and its derivatives along the face parameters.
struct UvSample {
    glm::dvec2 uv{0.0}, du{0.0}, dv{0.0};
};

class UvMap {
  public:
    /// Throws ArgumentError if the mesh has no texture coordinates.
    explicit UvMap(const ControlMesh& mesh, UvInterpolation rule = UvInterpolation::Mesh);

    /// The UV of (ptex face, u, v), u and v in [0, 1], with its derivatives.
    UvSample evaluate(int ptexFace, double u, double v) const;
    glm::dvec2 operator()(int ptexFace, double u, double v) const { return evaluate(ptexFace, u, v).uv; }

    /// The corner UVs of a ptex face at (u, v) = (0, 0), (1, 0), (1, 1), (0, 1) that the linear
    /// rule interpolates bilinearly (a sub-face of a non-quad: its corner, edge midpoints and
    /// centroid). Throws ArgumentError for a face out of range.
    const std::array<glm::dvec2, 4>& linearCorners(int ptexFace) const {
        if (ptexFace < 0 || ptexFace >= ptexFaceCount())
            throw ArgumentError(name_ + ": ptex face " + std::to_string(ptexFace) + " out of range [0, " +
                                std::to_string(ptexFaceCount()) + ")");
        return corners_[static_cast<std::size_t>(ptexFace)];
    }
    /// Whether the UVs are subdivided (a smooth rule), not interpolated linearly.
    bool smooth() const { return smooth_; }
    /// The Sdc rule in use (FVAR_LINEAR_ALL for Linear).
    Sdc::Options::FVarLinearInterpolation rule() const { return rule_; }
    int ptexFaceCount() const { return static_cast<int>(ptexBase_.size()); }
    /// The base face a ptex face belongs to.
    int baseFace(int ptexFace) const { return ptexBase_[static_cast<std::size_t>(ptexFace)]; }
    /// Whether a ptex face is a sub-face of a non-quad (its edges are half base edges).
    bool isSubFace(int ptexFace) const { return subFace_[static_cast<std::size_t>(ptexFace)] >= 0; }
    const std::string& meshName() const { return name_; }

  private:
    struct Smooth {
        Bfr::Surface<double> surface;
        std::vector<double> patchPoints; // 2 per point
        int subFace = -1;                // the ptex sub-face of a non-quad, else -1
    };
    UvSample linear(int ptexFace, double u, double v) const;

    std::string name_;
    bool smooth_ = false;
    Sdc::Options::FVarLinearInterpolation rule_ = Sdc::Options::FVAR_LINEAR_ALL;
    std::vector<int> ptexBase_;
    std::vector<std::array<glm::dvec2, 4>> corners_; // linear: per ptex face
    std::vector<std::shared_ptr<const Smooth>> smoothFaces_; // per base face; null for holes (linear there)
    std::vector<int> subFace_;                               // per ptex face: its sub-face, -1 for a quad
};

inline UvMap::UvMap(const ControlMesh& mesh, UvInterpolation rule) : name_(mesh.description().name) {
    if (!mesh.hasUVs())
        throw ArgumentError(name_ + ": mesh has no texture coordinates, so a map cannot be placed on it");
    const MeshDescription& d = mesh.description();
    const Far::TopologyLevel& L = mesh.base();
    ptexBase_.resize(static_cast<std::size_t>(mesh.ptexFaceCount()));
    corners_.resize(ptexBase_.size());
    subFace_.assign(ptexBase_.size(), -1);
    for (int f = 0; f < L.GetNumFaces(); ++f) {
        const int n = L.GetFaceVertices(f).size();
        const int at = mesh.faceOffset(f);
        std::vector<glm::dvec2> uv(static_cast<std::size_t>(n));
        glm::dvec2 centre(0.0);
        for (int j = 0; j < n; ++j) {
            uv[static_cast<std::size_t>(j)] = d.uvs[static_cast<std::size_t>(d.faceUVs[static_cast<std::size_t>(at + j)])];
            centre += uv[static_cast<std::size_t>(j)] / static_cast<double>(n);
        }
        const int first = mesh.ptex().GetFaceId(f);
        if (n == 4) {
            corners_[static_cast<std::size_t>(first)] = {uv[0], uv[1], uv[2], uv[3]};
            ptexBase_[static_cast<std::size_t>(first)] = f;
        } else {
            for (int k = 0; k < n; ++k) {
                const glm::dvec2 a = uv[static_cast<std::size_t>(k)];
                const glm::dvec2 b = uv[static_cast<std::size_t>((k + 1) % n)];
                const glm::dvec2 p = uv[static_cast<std::size_t>((k + n - 1) % n)];
                corners_[static_cast<std::size_t>(first + k)] = {a, 0.5 * (a + b), centre, 0.5 * (a + p)};
                ptexBase_[static_cast<std::size_t>(first + k)] = f;
                subFace_[static_cast<std::size_t>(first + k)] = k;
            }
        }
    }
    switch (rule) {
    case UvInterpolation::Mesh: rule_ = d.fvarLinear; break;
    case UvInterpolation::Linear: rule_ = Sdc::Options::FVAR_LINEAR_ALL; break;
    case UvInterpolation::Smooth: rule_ = Sdc::Options::FVAR_LINEAR_NONE; break;
    case UvInterpolation::CornersOnly: rule_ = Sdc::Options::FVAR_LINEAR_CORNERS_ONLY; break;
    case UvInterpolation::CornersPlus1: rule_ = Sdc::Options::FVAR_LINEAR_CORNERS_PLUS1; break;
    case UvInterpolation::CornersPlus2: rule_ = Sdc::Options::FVAR_LINEAR_CORNERS_PLUS2; break;
    case UvInterpolation::Boundaries: rule_ = Sdc::Options::FVAR_LINEAR_BOUNDARIES; break;
    }
    smooth_ = rule_ != Sdc::Options::FVAR_LINEAR_ALL;
    if (!smooth_) return;
    // The refiner lives only while the surfaces are made: each Bfr surface copies what it needs.
    const std::unique_ptr<Far::TopologyRefiner> refiner = mesh.createRefiner(rule_);
    Bfr::RefinerSurfaceFactory<>::Options fo;
    fo.SetDefaultFVarID(0);
    const Bfr::RefinerSurfaceFactory<> factory(*refiner, fo);
    smoothFaces_.resize(static_cast<std::size_t>(L.GetNumFaces()));
    for (int f = 0; f < L.GetNumFaces(); ++f) {
        auto s = std::make_shared<Smooth>();
        if (!factory.InitFaceVaryingSurface(f, &s->surface)) continue; // a hole: linear
        s->patchPoints.resize(2 * static_cast<std::size_t>(s->surface.GetNumPatchPoints()));
        const Bfr::Surface<double>::PointDescriptor pd(2);
        s->surface.PreparePatchPoints(&d.uvs[0].x, pd, s->patchPoints.data(), pd);
        smoothFaces_[static_cast<std::size_t>(f)] = std::move(s);
    }
}

inline UvSample UvMap::linear(int t, double u, double v) const {
    const auto& c = corners_[static_cast<std::size_t>(t)];
    UvSample s;
    s.uv = (1 - u) * (1 - v) * c[0] + u * (1 - v) * c[1] + u * v * c[2] + (1 - u) * v * c[3];
    s.du = (1 - v) * (c[1] - c[0]) + v * (c[2] - c[3]);
    s.dv = (1 - u) * (c[3] - c[0]) + u * (c[2] - c[1]);
    return s;
}

inline UvSample UvMap::evaluate(int t, double u, double v) const {
    if (t < 0 || t >= ptexFaceCount())
        throw ArgumentError(name_ + ": ptex face " + std::to_string(t) + " out of range [0, " +
                            std::to_string(ptexFaceCount()) + ")");
    if (!smooth_) return linear(t, u, v);
    const Smooth* s = smoothFaces_[static_cast<std::size_t>(baseFace(t))].get();
    if (!s) return linear(t, u, v);
    const Bfr::Parameterization param = s->surface.GetParameterization();
    const int sub = subFace_[static_cast<std::size_t>(t)];
    double coord[2] = {u, v};
    double scale = 1.0; // d(face coordinate) / d(ptex coordinate)
    if (sub >= 0) {
        // Bfr's quad sub-faces are half-size, unrotated copies of the ptex sub-face's square
        // (checked against Bfr's own linear evaluation in tests/test_map_source.cpp).
        const double in[2] = {u, v};
        param.ConvertNormalizedSubFaceToCoord(sub, in, coord);
        scale = 0.5;
    }
    const Bfr::Surface<double>::PointDescriptor pd(2);
    double p[2], du[2], dv[2];
    s->surface.Evaluate(coord, s->patchPoints.data(), pd, p, du, dv);
    return {{p[0], p[1]}, {scale * du[0], scale * du[1]}, {scale * dv[0], scale * dv[1]}};
}

/// A tessellated mesh with texture coordinates: its vertices split where the triangles that
/// meet at a vertex read different UVs (a UV seam: one copy per chart, at the same position
/// with the same normal, so the surface stays watertight by position), and the UV of every
/// vertex.
struct TexturedMesh {
    TriangleMesh mesh;
    std::vector<glm::dvec2> texcoords;
};

/// The UVs of `m` under `uvs`: each triangle corner's UV is that of its tile's (face, u, v)
/// (TriangleMesh::triangleFaces, triangleUVs); corners of one vertex within `tolerance` of
/// each other share a copy. Throws ArgumentError for a mesh whose arrays disagree or a face
/// out of range.
inline TexturedMesh texturedMesh(const TriangleMesh& m, const UvMap& uvs, double tolerance = 1e-9) {
    const std::size_t nv = m.positions.size(), nt = m.triangles.size();
    if (m.normals.size() != nv || m.faces.size() != nv || m.uvs.size() != nv || m.resolutions.size() != nv ||
        m.triangleFaces.size() != nt || m.triangleUVs.size() != nt)
        throw ArgumentError("texturedMesh: the mesh's arrays disagree in length");
    TexturedMesh out;
    out.mesh = m;
    out.texcoords.assign(nv, glm::dvec2(0.0));
    std::vector<std::vector<std::pair<glm::dvec2, int>>> copies(nv); // per original vertex: (uv, vertex id)
    for (std::size_t j = 0; j < nt; ++j)
        for (int c = 0; c < 3; ++c) {
            const int v = m.triangles[j][c];
            if (v < 0 || static_cast<std::size_t>(v) >= nv) throw ArgumentError("texturedMesh: triangle " + std::to_string(j) + " out of range");
            const glm::dvec2 q = m.triangleUVs[j][static_cast<std::size_t>(c)];
            const glm::dvec2 t = uvs(m.triangleFaces[j], q.x, q.y);
            auto& list = copies[static_cast<std::size_t>(v)];
            int id = -1;
            for (const auto& [uv, vid] : list)
                if (std::abs(uv.x - t.x) <= tolerance && std::abs(uv.y - t.y) <= tolerance) id = vid;
            if (id < 0) {
                if (list.empty()) {
                    id = v;
                    out.texcoords[static_cast<std::size_t>(v)] = t;
                } else {
                    id = static_cast<int>(out.mesh.positions.size());
                    const std::size_t o = static_cast<std::size_t>(v);
                    out.mesh.positions.push_back(m.positions[o]);
                    out.mesh.normals.push_back(m.normals[o]);
                    out.mesh.faces.push_back(m.faces[o]);
                    out.mesh.uvs.push_back(m.uvs[o]);
                    out.mesh.resolutions.push_back(m.resolutions[o]);
                    out.texcoords.push_back(t);
                }
                list.emplace_back(t, id);
            }
            out.mesh.triangles[j][c] = id;
        }
    return out;
}

} // namespace dispmap
