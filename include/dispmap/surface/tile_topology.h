#pragma once
// TileTopology: how the tiles of a control mesh meet, derived from OpenSubdiv's base level.
//
// One tile per Ptex face (Far::PtexIndices numbering): a quad face is one tile; an N-gon
// (N != 4) is N tiles, sub-face k having corners (vertex k, midpoint of face edge k, face
// centre, midpoint of face edge k-1), as Ptex and OpenSubdiv's Bfr parameterise them.
//
// Vertices get one id space: base vertices [0, nv), edge midpoints nv + edge, face centres
// nv + ne + face. Each tile edge i (corner i to corner i+1) lies on a "segment": a base edge
// (quads: all of it; sub-faces: half of it) or a spoke inside an N-gon (edge midpoint to
// centre). Tiles that share a segment are linked by an affine map between their edge
// parameters. This handles the T-junction where a quad meets two sub-faces of an N-gon: the
// quad's edge links to two half-length sub-face edges.
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "dispmap/surface/mesh.h"

namespace dispmap {

class TileTopology {
  public:
    /// A neighbour across (part of) a tile edge: for my edge parameter y in [y0, y1] (0 at my
    /// corner i, 1 at corner i+1) the neighbour's edge parameter is z = alpha - beta * y.
    /// beta is 1 for equal edges, 2 or 1/2 at a quad/sub-face T-junction.
    struct Link {
        int tile = -1, edge = -1;
        double alpha = 0, beta = 1, y0 = 0, y1 = 1;
    };
    /// How a vertex constrains the tile corners around it (tile_builder.h).
    enum class VertexKind {
        Regular,         ///< interior vertex with 4 tiles: corner overlap from the diagonal tile
        BoundaryRegular, ///< boundary vertex with 1 or 2 tiles: overlap extrapolated
        Constrained,     ///< any other: Doo-Sabin corner constraint (§4.2), D_u = D_v = 0
        TJunction,       ///< edge midpoint where two sub-faces meet one quad edge
    };

    explicit TileTopology(const ControlMesh& mesh);

    int tileCount() const { return static_cast<int>(corners_.size()); }
    int baseFace(int t) const { return face_[idx(t)]; }
    /// -1 for a quad's tile, else the corner k of the N-gon this sub-face belongs to.
    int subFace(int t) const { return sub_[idx(t)]; }
    /// 1 for a sub-face tile (its edges are half as long in the base mesh), 0 for a quad.
    int scale(int t) const { return subFace(t) < 0 ? 0 : 1; }
    /// (u, v) of tile corner c: 0 at (0,0), 1 at (1,0), 2 at (1,1), 3 at (0,1).
    static glm::dvec2 cornerUV(int c) { return glm::dvec2((c & 3) == 1 || (c & 3) == 2 ? 1.0 : 0.0, (c & 3) >= 2 ? 1.0 : 0.0); }
    int cornerVertex(int t, int c) const { return corners_[idx(t)][static_cast<std::size_t>(c & 3)]; }
    const std::vector<Link>& links(int t, int e) const { return links_[idx(t)][static_cast<std::size_t>(e & 3)]; }
    int vertexCount() const { return static_cast<int>(incidence_.size()); }
    /// (tile, corner) pairs at vertex v.
    const std::vector<std::pair<int, int>>& incidences(int v) const { return incidence_[static_cast<std::size_t>(v)]; }
    VertexKind kind(int v) const { return kind_[static_cast<std::size_t>(v)]; }
    bool isBoundaryEdge(int t, int e) const { return links(t, e).empty(); }
    /// The link of edge e whose range contains y (nullptr at a boundary).
    const Link* linkAt(int t, int e, double y) const {
        for (const Link& l : links(t, e))
            if (y >= l.y0 && y <= l.y1) return &l;
        return nullptr;
    }

  private:
    static std::size_t idx(int t) { return static_cast<std::size_t>(t); }
    std::vector<int> face_, sub_;
    std::vector<std::array<int, 4>> corners_;
    std::vector<std::array<std::vector<Link>, 4>> links_;
    std::vector<std::vector<std::pair<int, int>>> incidence_;
    std::vector<VertexKind> kind_;
};

inline TileTopology::TileTopology(const ControlMesh& mesh) {
    const Far::TopologyLevel& L = mesh.base();
    const int nv = L.GetNumVertices(), ne = L.GetNumEdges(), nf = L.GetNumFaces();
    const int n = mesh.ptexFaceCount();
    face_.assign(idx(n), -1);
    sub_.assign(idx(n), -1);
    corners_.resize(idx(n));
    links_.resize(idx(n));
    incidence_.resize(static_cast<std::size_t>(nv + ne + nf));
    kind_.assign(incidence_.size(), VertexKind::Regular);

    // Segment of every tile edge: id and the segment parameter x at y = 0 and y = 1.
    struct Seg {
        long id;
        double x0, x1;
    };
    std::vector<std::array<Seg, 4>> seg(idx(n));
    int spokeBase = ne;
    for (int f = 0; f < nf; ++f) {
        auto fv = L.GetFaceVertices(f);
        auto fe = L.GetFaceEdges(f);
        const int N = fv.size();
        const int first = mesh.ptex().GetFaceId(f);
        auto xAt = [&](int e, int v) { return L.GetEdgeVertices(e)[0] == v ? 0.0 : 1.0; };
        if (N == 4) {
            for (int i = 0; i < 4; ++i) {
                const int e = fe[i];
                corners_[idx(first)][static_cast<std::size_t>(i)] = fv[i];
                seg[idx(first)][static_cast<std::size_t>(i)] = Seg{e, xAt(e, fv[i]), xAt(e, fv[(i + 1) % 4])};
            }
            face_[idx(first)] = f;
        } else {
            for (int k = 0; k < N; ++k) {
                const int t = first + k;
                const int ek = fe[k], ep = fe[(k + N - 1) % N];
                face_[idx(t)] = f;
                sub_[idx(t)] = k;
                corners_[idx(t)] = {fv[k], nv + ek, nv + ne + f, nv + ep};
                seg[idx(t)][0] = Seg{ek, xAt(ek, fv[k]), 0.5};
                seg[idx(t)][1] = Seg{spokeBase + k, 0.0, 1.0};
                seg[idx(t)][2] = Seg{spokeBase + (k + N - 1) % N, 1.0, 0.0};
                seg[idx(t)][3] = Seg{ep, 0.5, xAt(ep, fv[k])};
            }
            spokeBase += N;
        }
    }
    for (int t = 0; t < n; ++t)
        if (face_[idx(t)] < 0) throw MeshError(mesh.description().name + ": Ptex face " + std::to_string(t) + " has no face");

    // Link tile edges that share a segment and overlap on it.
    std::map<long, std::vector<std::pair<int, int>>> bySegment;
    for (int t = 0; t < n; ++t)
        for (int e = 0; e < 4; ++e) bySegment[seg[idx(t)][static_cast<std::size_t>(e)].id].emplace_back(t, e);
    for (const auto& [id, edges] : bySegment) {
        for (const auto& [ta, ea] : edges)
            for (const auto& [tb, eb] : edges) {
                if (ta == tb && ea == eb) continue;
                const Seg& A = seg[idx(ta)][static_cast<std::size_t>(ea)];
                const Seg& B = seg[idx(tb)][static_cast<std::size_t>(eb)];
                const double lo = std::max(std::min(A.x0, A.x1), std::min(B.x0, B.x1));
                const double hi = std::min(std::max(A.x0, A.x1), std::max(B.x0, B.x1));
                if (hi - lo <= 0.0) continue;
                const double dA = A.x1 - A.x0, dB = B.x1 - B.x0;
                Link l;
                l.tile = tb;
                l.edge = eb;
                l.alpha = (A.x0 - B.x0) / dB;
                l.beta = -dA / dB;
                if (l.beta <= 0.0)
                    throw MeshError(mesh.description().name + ": faces " + std::to_string(face_[idx(ta)] + 1) + " and " +
                                    std::to_string(face_[idx(tb)] + 1) + " have opposite orientations");
                const double ya = (lo - A.x0) / dA, yb = (hi - A.x0) / dA;
                l.y0 = std::min(ya, yb);
                l.y1 = std::max(ya, yb);
                links_[idx(ta)][static_cast<std::size_t>(ea)].push_back(l);
            }
    }

    // Vertices: incidences and kinds.
    for (int t = 0; t < n; ++t)
        for (int c = 0; c < 4; ++c) incidence_[static_cast<std::size_t>(cornerVertex(t, c))].emplace_back(t, c);
    for (std::size_t v = 0; v < incidence_.size(); ++v) {
        const auto& inc = incidence_[v];
        if (inc.empty()) continue;
        bool boundary = false;
        for (const auto& [t, c] : inc)
            if (!linkAt(t, c, 0.0) || !linkAt(t, (c + 3) & 3, 1.0)) boundary = true;
        const bool midpoint = v >= static_cast<std::size_t>(nv) && v < static_cast<std::size_t>(nv + ne);
        bool tjunction = false;
        if (midpoint && !boundary) {
            const int e = static_cast<int>(v) - nv;
            for (int f : L.GetEdgeFaces(e))
                if (L.GetFaceVertices(f).size() == 4) tjunction = true;
        }
        if (tjunction)
            kind_[v] = VertexKind::TJunction;
        else if (!boundary && inc.size() == 4)
            kind_[v] = VertexKind::Regular;
        else if (boundary && inc.size() <= 2)
            kind_[v] = VertexKind::BoundaryRegular;
        else
            kind_[v] = VertexKind::Constrained;
    }
}

} // namespace dispmap
