#pragma once
// From an initial control mesh (ICM) to the optimised base mesh (OBM) of a bake (Huang & Feng
// 2017, §3.1.2 and §3.2):
//  1. progressive interpolation of Catmull-Clark subdivision (Chen et al. 2008) on the ICM, so
//     that its limit surface passes through the ICM's own vertices instead of shrinking away
//     from them: c_i <- c_i + (p_i - L_i(c)), where L_i is the limit position of vertex i;
//  2. one Catmull-Clark step (Far uniform refinement): the all-quad initial base mesh (IBM),
//     whose limit surface is the ICM's;
//  3. progressive fitting of the IBM to the dense mesh: sample the limit surface (samples per
//     face edge m, at ((i + 1/2)/m, (j + 1/2)/m)), find for each sample its nearest point on the
//     dense mesh in the paper's position+normal sense: the closest point of the dense surface
//     (Embree) when that surface faces the same way as the sample (their normals' dot > 0), else
//     the nearest dense vertex in the six-dimensional space (x, w n) (the feature-sensitive
//     metric the paper takes from Pottmann et al.; w = normalWeight x the bounding-box
//     diagonal), which keeps a sample from snapping onto the far side of a thin part. (The paper
//     takes the 6D-nearest vertex always; its distance cannot fall below the vertex spacing,
//     so the fit would stall there on a scan sampled coarser than the detail.) Then move
//     each control point by the weighted mean of its samples' difference vectors,
//     Delta_i = sum_j w_ij delta_j / sum_j w_ij, with w_ij the limit stencil weight of control
//     point i at sample j (OpenSubdiv's Far::LimitStencilTable: B-spline patches, Gregory end caps
//     around extraordinary vertices, where the paper used Loop & Schaefer's bicubic
//     approximation everywhere). Two-sided (FitOptions::twoSided): a subset of the dense vertices
//     also pull their nearest samples, so that the base surface grows into protrusions whose
//     points are nobody's closest point. The first update is smoothed (the paper's Laplacian
//     against self-intersections, applied to the update so that it does not shrink the mesh).
//     Stops when the score (the RMS of |delta|, or with twoSided the root sum of squares of the
//     two directions' RMS) is below rmsThreshold of the diagonal, after maxIterations, when an
//     iteration gains less than 1 %, or when one makes it worse (that update is undone).
// Every stage that is parallel in nature runs on all cores through TBB (the samples, the nearest
// vertices, the control points' updates); the result does not depend on the thread count.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nanoflann.hpp>
#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/stencilTableFactory.h>
#include <tbb/parallel_for.h>

#include "dispmap/bake/dense_mesh.h"
#include "dispmap/bake/ray_scene.h"
#include "dispmap/surface/mesh.h"

namespace dispmap {

struct FitOptions {
    int interpolationSteps = 2;  ///< progressive interpolation steps on the ICM (the paper: one or two)
    int samplesPerEdge = 8;      ///< fitting samples per IBM face edge (the paper's tessfactor)
    int maxIterations = 30;      ///< the paper stops after at most five; ours gains 1 % or more an iteration for ~25 (a CPU iteration costs ~50 ms on a 300-face base)
    double rmsThreshold = 1e-3;  ///< stop below this RMS, a fraction of the diagonal (the paper's 0.1 %)
    double normalWeight = 0.05;  ///< weight of the normal in the 6D metric, x the diagonal
    bool laplacianFirst = true;  ///< smooth after the first update (the paper does)
    int stencilIsolation = 4;    ///< adaptive isolation of the stencils' patches near extraordinary vertices
    bool twoSided = true;        ///< also pull samples towards the dense vertices nearest to them (below)
};

/// Most fitting samples a fit takes (OpenSubdiv's stencil tables index with int; ~40 stencil
/// entries per sample at 16 bytes each is ~10 GB here).
inline constexpr std::uint64_t kMaxFitSamples = std::uint64_t{1} << 24;

struct FitIteration {
    double rmsPercent = 0; ///< RMS of |delta|, % of the diagonal, before this iteration's update
    double maxPercent = 0; ///< max |delta|, % of the diagonal
    double seconds = 0;
    double reverseRmsPercent = 0; ///< RMS distance from the dense vertices (a subset) to their nearest samples (two-sided)
    bool undone = false;   ///< worse than the iteration before: its update was undone and the fit ended
};

struct FitReport {
    std::vector<FitIteration> iterations; ///< one per evaluation (the last may be undone)
    long samples = 0;
    /// The iteration whose mesh is the result: the last one not undone.
    const FitIteration& result() const {
        for (auto it = iterations.rbegin(); it != iterations.rend(); ++it)
            if (!it->undone) return *it;
        return iterations.front();
    }
};

/// Nearest dense vertex in the 6D space (x, w n): a k-d tree (nanoflann) over the dense vertices.
class DenseVertexIndex {
  public:
    DenseVertexIndex(const DenseMesh& dense, double normalWeight)
        : points_(dense.positions.size() * 6), weight_(static_cast<float>(normalWeight * dense.diagonal())) {
        const std::vector<glm::vec3> n = denseVertexNormals(dense);
        for (std::size_t i = 0; i < dense.positions.size(); ++i)
            for (int c = 0; c < 3; ++c) {
                points_[6 * i + static_cast<std::size_t>(c)] = dense.positions[i][c];
                points_[6 * i + 3 + static_cast<std::size_t>(c)] = weight_ * n[i][c];
            }
        tree_ = std::make_unique<Tree>(6, *this, nanoflann::KDTreeSingleIndexAdaptorParams(16));
        tree_->buildIndex();
    }
    // The tree holds a reference to this object (nanoflann's dataset): no copies, no moves.
    DenseVertexIndex(const DenseVertexIndex&) = delete;
    DenseVertexIndex& operator=(const DenseVertexIndex&) = delete;
    /// The dense vertex nearest to (p, w n) for a unit normal n.
    std::uint32_t nearest(const glm::dvec3& p, const glm::dvec3& n) const {
        const float q[6] = {static_cast<float>(p.x),           static_cast<float>(p.y),           static_cast<float>(p.z),
                            weight_ * static_cast<float>(n.x), weight_ * static_cast<float>(n.y), weight_ * static_cast<float>(n.z)};
        std::uint32_t index = 0;
        float d2 = 0.0f;
        tree_->knnSearch(q, 1, &index, &d2);
        return index;
    }
    // nanoflann's dataset interface
    std::size_t kdtree_get_point_count() const { return points_.size() / 6; }
    float kdtree_get_pt(std::size_t i, std::size_t dim) const { return points_[6 * i + dim]; }
    template <class Box> bool kdtree_get_bbox(Box&) const { return false; }

  private:
    using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, DenseVertexIndex>, DenseVertexIndex, 6,
                                                     std::uint32_t>;
    std::vector<float> points_;
    float weight_;
    std::unique_ptr<Tree> tree_;
};

namespace detail {
/// Fitting samples as a nanoflann point cloud (the reverse direction's nearest-sample search).
struct SamplePoints {
    const std::vector<glm::dvec3>* p;
    std::size_t kdtree_get_point_count() const { return p->size(); }
    double kdtree_get_pt(std::size_t i, std::size_t dim) const { return (*p)[i][static_cast<glm::length_t>(dim)]; }
    template <class Box> bool kdtree_get_bbox(Box&) const { return false; }
};
using SampleTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, SamplePoints>, SamplePoints, 3, std::uint32_t>;
} // namespace detail

/// Limit stencils (position and first derivatives) of a control mesh at Ptex locations, as
/// sparse rows over the control vertices.
struct LimitStencils {
    std::vector<int> offsets, sizes, indices;
    std::vector<double> w, du, dv;
    int count() const { return static_cast<int>(sizes.size()); }
};

/// One location per entry: (ptexFace, u, v).
struct PtexLocation {
    int face = 0;
    double u = 0, v = 0;
};

inline LimitStencils limitStencils(const ControlMesh& mesh, const std::vector<PtexLocation>& at, int isolation) {
    std::unique_ptr<Far::TopologyRefiner> refiner = mesh.createRefiner();
    Far::TopologyRefiner::AdaptiveOptions ao(isolation);
    refiner->RefineAdaptive(ao);
    // One location array per run of consecutive locations on the same face; the stencils come
    // out in the given order.
    std::vector<double> s(at.size()), t(at.size());
    Far::LimitStencilTableFactoryReal<double>::LocationArrayVec arrays;
    for (std::size_t i = 0; i < at.size();) {
        std::size_t j = i;
        while (j < at.size() && at[j].face == at[i].face) {
            s[j] = at[j].u;
            t[j] = at[j].v;
            ++j;
        }
        Far::LimitStencilTableFactoryReal<double>::LocationArray a;
        a.ptexIdx = at[i].face;
        a.numLocations = static_cast<int>(j - i);
        a.s = &s[i];
        a.t = &t[i];
        arrays.push_back(a);
        i = j;
    }
    std::unique_ptr<const Far::LimitStencilTableReal<double>> table(
        Far::LimitStencilTableFactoryReal<double>::Create(*refiner, arrays));
    if (!table || table->GetNumStencils() != static_cast<int>(at.size()))
        throw MeshError(mesh.description().name + ": OpenSubdiv could not build the limit stencils");
    LimitStencils out;
    out.sizes = table->GetSizes();
    out.offsets.assign(table->GetOffsets().begin(), table->GetOffsets().end());
    out.indices.assign(table->GetControlIndices().begin(), table->GetControlIndices().end());
    out.w = table->GetWeights();
    out.du = table->GetDuWeights();
    out.dv = table->GetDvWeights();
    return out;
}

/// The limit stencil of every base vertex (at one of its faces' corners).
inline LimitStencils vertexLimitStencils(const ControlMesh& mesh, int isolation) {
    const Far::TopologyLevel& L = mesh.base();
    std::vector<PtexLocation> at(static_cast<std::size_t>(L.GetNumVertices()));
    for (int v = 0; v < L.GetNumVertices(); ++v) {
        const Far::ConstIndexArray faces = L.GetVertexFaces(v);
        if (faces.size() == 0) throw MeshError(mesh.description().name + ": vertex " + std::to_string(v + 1) + " is on no face");
        const int f = faces[0];
        const Far::ConstIndexArray fv = L.GetFaceVertices(f);
        int c = 0;
        while (fv[c] != v) ++c;
        PtexLocation& p = at[static_cast<std::size_t>(v)];
        if (fv.size() == 4) {
            static constexpr double cu[4] = {0, 1, 1, 0}, cv[4] = {0, 0, 1, 1};
            p = {mesh.ptex().GetFaceId(f), cu[c], cv[c]};
        } else {
            p = {mesh.ptex().GetFaceId(f) + c, 0.0, 0.0};
        }
    }
    // One location array per run of the same face, in this order: the rows come out in vertex
    // order (the factory takes any number of arrays per face).
    return limitStencils(mesh, at, isolation);
}

/// Progressive interpolation (Chen et al. 2008): `steps` times c_i += p_i - L_i(c), with p the
/// ICM's own vertices. Returns the moved description (same topology).
inline MeshDescription progressiveInterpolation(const MeshDescription& icm, int steps, int isolation = 4) {
    MeshDescription out = icm;
    if (steps <= 0) return out;
    const ControlMesh mesh(icm);
    const LimitStencils st = vertexLimitStencils(mesh, isolation);
    for (int step = 0; step < steps; ++step) {
        std::vector<glm::dvec3> moved = out.positions;
        for (int v = 0; v < st.count(); ++v) {
            glm::dvec3 limit(0.0);
            for (int k = 0; k < st.sizes[static_cast<std::size_t>(v)]; ++k) {
                const std::size_t o = static_cast<std::size_t>(st.offsets[static_cast<std::size_t>(v)] + k);
                limit += st.w[o] * out.positions[static_cast<std::size_t>(st.indices[o])];
            }
            moved[static_cast<std::size_t>(v)] += icm.positions[static_cast<std::size_t>(v)] - limit;
        }
        out.positions = std::move(moved);
    }
    return out;
}

/// One uniform Catmull-Clark step (Far, double-precision weights): the all-quad mesh with the
/// same limit surface. Throws ArgumentError for a mesh with creases, corners, holes or
/// non-default rules (their refined form is not carried over; neither route makes them).
inline MeshDescription catmullClarkStep(const MeshDescription& icm) {
    if (!icm.creaseWeights.empty() || !icm.cornerWeights.empty() || !icm.holes.empty() ||
        icm.creasing != Sdc::Options::CREASE_UNIFORM || icm.triangles != Sdc::Options::TRI_SUB_CATMARK)
        throw ArgumentError(icm.name + ": a base mesh for baking may not have creases, corners, holes or non-default rules");
    const ControlMesh mesh(icm);
    std::unique_ptr<Far::TopologyRefiner> r = mesh.createRefiner();
    r->RefineUniform(Far::TopologyRefiner::UniformOptions(1));
    const Far::TopologyLevel& L1 = r->GetLevel(1);
    struct V {
        glm::dvec3 p{0};
        void Clear(void* = nullptr) { p = glm::dvec3(0.0); }
        void AddWithWeight(const V& s, double w) { p += w * s.p; }
    };
    std::vector<V> src(icm.positions.size()), dst(static_cast<std::size_t>(L1.GetNumVertices()));
    for (std::size_t i = 0; i < src.size(); ++i) src[i].p = icm.positions[i];
    Far::PrimvarRefinerReal<double>(*r).Interpolate(1, src, dst);
    MeshDescription out;
    out.name = icm.name;
    out.boundary = icm.boundary;
    for (const V& v : dst) out.positions.push_back(v.p);
    for (int f = 0; f < L1.GetNumFaces(); ++f) {
        const Far::ConstIndexArray fv = L1.GetFaceVertices(f);
        out.faceSizes.push_back(fv.size());
        for (int k = 0; k < fv.size(); ++k) out.faceVertices.push_back(fv[k]);
    }
    return out;
}

/// Progressive fitting of `ibm` to the dense mesh (step 3 above). Returns the moved mesh.
/// `progress` (if set) receives the fraction of maxIterations done after each iteration, from
/// the calling thread.
inline MeshDescription fitToDense(const MeshDescription& ibm, const DenseMesh& dense, const RayScene& scene,
                                  const DenseVertexIndex& index, const FitOptions& options = {}, FitReport* report = nullptr,
                                  const std::function<void(double)>& progress = {}) {
    if (options.samplesPerEdge < 1 || options.samplesPerEdge > 64 || options.maxIterations < 0)
        throw ArgumentError("fitting: samples per edge must be in [1, 64] and iterations >= 0");
    const ControlMesh mesh(ibm);
    const int m = options.samplesPerEdge;
    if (static_cast<std::uint64_t>(mesh.ptexFaceCount()) * static_cast<std::uint64_t>(m * m) > kMaxFitSamples)
        throw ArgumentError(ibm.name + ": " + std::to_string(mesh.ptexFaceCount()) + " faces x " + std::to_string(m * m) +
                            " fitting samples are more than the " + std::to_string(kMaxFitSamples) +
                            " a fit may take: fewer base faces or fewer fitting samples");
    std::vector<PtexLocation> at;
    at.reserve(static_cast<std::size_t>(mesh.ptexFaceCount() * m * m));
    for (int f = 0; f < mesh.ptexFaceCount(); ++f)
        for (int j = 0; j < m; ++j)
            for (int i = 0; i < m; ++i) at.push_back({f, (i + 0.5) / m, (j + 0.5) / m});
    const LimitStencils st = limitStencils(mesh, at, options.stencilIsolation);
    const std::size_t ns = at.size(), nc = ibm.positions.size();

    // Transpose: per control point, its (sample, weight) pairs, for a parallel, ordered update.
    std::vector<int> colStart(nc + 1, 0);
    for (std::size_t s = 0; s < ns; ++s)
        for (int k = 0; k < st.sizes[s]; ++k) ++colStart[static_cast<std::size_t>(st.indices[static_cast<std::size_t>(st.offsets[s] + k)]) + 1];
    for (std::size_t c = 0; c < nc; ++c) colStart[c + 1] += colStart[c];
    std::vector<int> colSample(static_cast<std::size_t>(colStart[nc]));
    std::vector<double> colWeight(colSample.size());
    {
        std::vector<int> fill(colStart.begin(), colStart.end() - 1);
        for (std::size_t s = 0; s < ns; ++s)
            for (int k = 0; k < st.sizes[s]; ++k) {
                const std::size_t o = static_cast<std::size_t>(st.offsets[s] + k);
                const std::size_t at2 = static_cast<std::size_t>(fill[static_cast<std::size_t>(st.indices[o])]++);
                colSample[at2] = static_cast<int>(s);
                colWeight[at2] = st.w[o];
            }
    }
    // Neighbours for the smoothing of the first update (the mesh's edges).
    const Far::TopologyLevel& L = mesh.base();

    MeshDescription out = ibm;
    std::vector<glm::dvec3> delta(ns), position(ns);
    // The reverse direction: a subset of the dense vertices (at most 4 per sample), each pulling
    // its nearest sample towards itself. Without it nothing pulls the base surface into a
    // protrusion whose points are nobody's closest point (a leg, an ear tip).
    const std::size_t stride = std::max<std::size_t>(1, dense.positions.size() / (4 * ns));
    std::vector<std::uint32_t> reverseVertices;
    if (options.twoSided)
        for (std::size_t v = 0; v < dense.positions.size(); v += stride) reverseVertices.push_back(static_cast<std::uint32_t>(v));
    std::vector<std::uint32_t> nearestSample(reverseVertices.size());
    FitReport rep;
    rep.samples = static_cast<long>(ns);
    const double diag = dense.diagonal();
    double previous = std::numeric_limits<double>::infinity();
    std::vector<glm::dvec3> best = out.positions;
    for (int it = 0;; ++it) {
        const auto t0 = std::chrono::steady_clock::now();
        const std::vector<glm::dvec3> c = out.positions;
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, ns, 256), [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t s = r.begin(); s != r.end(); ++s) {
                glm::dvec3 p(0.0), du(0.0), dv(0.0);
                for (int k = 0; k < st.sizes[s]; ++k) {
                    const std::size_t o = static_cast<std::size_t>(st.offsets[s] + k);
                    const glm::dvec3& x = c[static_cast<std::size_t>(st.indices[o])];
                    p += st.w[o] * x;
                    du += st.du[o] * x;
                    dv += st.dv[o] * x;
                }
                const glm::dvec3 cr = glm::cross(du, dv);
                const double l = glm::length(cr);
                const glm::dvec3 n = l > 0.0 ? cr / l : glm::dvec3(0.0);
                position[s] = p;
                const RayScene::Closest cl = scene.closest(glm::vec3(p));
                if (cl.found && glm::dot(glm::dvec3(scene.triangleNormal(cl.prim)), n) > 0.0)
                    delta[s] = glm::dvec3(cl.point) - p;
                else
                    delta[s] = glm::dvec3(dense.positions[index.nearest(p, n)]) - p;
            }
        });
        double sum = 0.0, mx = 0.0;
        for (const glm::dvec3& d : delta) {
            const double l2 = glm::dot(d, d);
            sum += l2;
            mx = std::max(mx, l2);
        }
        FitIteration fi;
        fi.rmsPercent = 100.0 * std::sqrt(sum / static_cast<double>(ns)) / diag;
        fi.maxPercent = 100.0 * std::sqrt(mx) / diag;
        double reverseSum = 0.0;
        if (!reverseVertices.empty()) {
            const detail::SamplePoints cloud{&position};
            detail::SampleTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
            tree.buildIndex();
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, reverseVertices.size(), 1024),
                              [&](const tbb::blocked_range<std::size_t>& r) {
                                  for (std::size_t i = r.begin(); i != r.end(); ++i) {
                                      const glm::dvec3 q(dense.positions[reverseVertices[i]]);
                                      const double qq[3] = {q.x, q.y, q.z};
                                      double d2 = 0.0;
                                      tree.knnSearch(qq, 1, &nearestSample[i], &d2);
                                  }
                              });
            // Each sample's difference: the mean of its own and of those of the dense vertices
            // whose nearest sample it is (in vertex order: the same sums on any thread count).
            std::vector<glm::dvec3> acc = delta;
            std::vector<double> count(ns, 1.0);
            for (std::size_t i = 0; i < reverseVertices.size(); ++i) {
                const std::size_t s = nearestSample[i];
                const glm::dvec3 d = glm::dvec3(dense.positions[reverseVertices[i]]) - position[s];
                acc[s] += d;
                count[s] += 1.0;
                reverseSum += glm::dot(d, d);
            }
            for (std::size_t s = 0; s < ns; ++s) delta[s] = acc[s] / count[s];
            fi.reverseRmsPercent = 100.0 * std::sqrt(reverseSum / static_cast<double>(reverseVertices.size())) / diag;
        }
        // What the fit minimises: both directions when two-sided.
        const double score = reverseVertices.empty() ? fi.rmsPercent : std::hypot(fi.rmsPercent, fi.reverseRmsPercent);
        // An iteration that made it worse is undone (the last update overshot), and ends the fit.
        if (score > previous) {
            out.positions = best;
            fi.undone = true;
        }
        const bool stop = it >= options.maxIterations || score < 100.0 * options.rmsThreshold || score > 0.99 * previous;
        if (score <= previous) best = out.positions;
        previous = std::min(previous, score);
        if (!stop) {
            std::vector<glm::dvec3> moved = c;
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nc, 64), [&](const tbb::blocked_range<std::size_t>& r) {
                for (std::size_t i = r.begin(); i != r.end(); ++i) {
                    glm::dvec3 num(0.0);
                    double den = 0.0;
                    for (int k = colStart[i]; k < colStart[i + 1]; ++k) {
                        num += colWeight[static_cast<std::size_t>(k)] * delta[static_cast<std::size_t>(colSample[static_cast<std::size_t>(k)])];
                        den += colWeight[static_cast<std::size_t>(k)];
                    }
                    if (den > 1e-9) moved[i] += num / den;
                }
            });
            if (it == 0 && options.laplacianFirst) {
                // The first update is smoothed: each control point moves by the mean of its own
                // and its neighbours' mean update. Smoothing the update rather than the points
                // does not shrink the mesh (a Laplacian of the points would, by about the
                // curvature times the edge length squared, undoing what the fit gains).
                std::vector<glm::dvec3> step(nc), smooth(nc);
                for (std::size_t i = 0; i < nc; ++i) step[i] = moved[i] - c[i];
                for (int v = 0; v < L.GetNumVertices(); ++v) {
                    const Far::ConstIndexArray e = L.GetVertexEdges(v);
                    glm::dvec3 avg(0.0);
                    for (int k = 0; k < e.size(); ++k) {
                        const Far::ConstIndexArray ev = L.GetEdgeVertices(e[k]);
                        avg += step[static_cast<std::size_t>(ev[0] == v ? ev[1] : ev[0])];
                    }
                    smooth[static_cast<std::size_t>(v)] =
                        c[static_cast<std::size_t>(v)] + 0.5 * step[static_cast<std::size_t>(v)] +
                        (e.size() > 0 ? 0.5 * avg / static_cast<double>(e.size()) : 0.5 * step[static_cast<std::size_t>(v)]);
                }
                moved = std::move(smooth);
            }
            out.positions = std::move(moved);
        }
        fi.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        rep.iterations.push_back(fi);
        if (stop) break;
        if (progress && options.maxIterations > 0) progress(static_cast<double>(it + 1) / options.maxIterations);
    }
    if (report) *report = rep;
    return out;
}

} // namespace dispmap
