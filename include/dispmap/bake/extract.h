#pragma once
// Displacement extraction by ray casting (Huang & Feng 2017 §3.3; Nießner & Loop 2013 §4.1):
// for every tile sample (the sub-patch centres ((i + 1/2)/s, (j + 1/2)/s) that the tile fit
// interpolates, surface/tile_builder.h), rays from the base surface point s along +N and -N,
// N = normalize(s_u x s_v) as the displaced surface uses it; D = the signed distance to the
// nearest hit within the shell |t| <= shell whose triangle faces the way N does (dot > 0).
// Along either ray a hit facing against N is passed over (up to kMaxRayHops of them): it is
// the far wall of a thin part (an ear seen from inside it) or a fold, not the surface above s.
//
// The rules for a sample without such a hit (counted in the report, never left as garbage):
//  * fold-over: there were hits, but all of them face against N. The dense surface folds back
//    over the base surface there, and no height along N describes it;
//  * miss: no triangle within the shell on either side (a hole in the scan, a base surface
//    that strays from the detail);
//  both are filled with the closest point c of the dense mesh: D = dot(c - s, N), clamped to
//  the shell. That is the height of the dense surface's nearest point seen along N: it keeps
//  D continuous with the neighbouring hits where the fold or hole is small.
#include <atomic>
#include <cmath>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

#include <tbb/parallel_for.h>

#include "dispmap/bake/ray_scene.h"
#include "dispmap/surface/base_surface.h"
#include "dispmap/surface/tile_builder.h"

namespace dispmap {

struct ExtractOptions {
    double shell = 0.05; ///< the rays' reach either side, a fraction of the dense mesh's diagonal
};

struct ExtractReport {
    long samples = 0, hits = 0, misses = 0, foldovers = 0;
    double maxAbs = 0; ///< largest |D|
};

/// Hits facing against N passed over along one ray before it counts as no hit.
inline constexpr int kMaxRayHops = 8;

namespace detail {
struct Side {
    bool found = false;   ///< a hit facing the way of N within the reach
    bool against = false; ///< a hit facing against N was passed over
    float t = 0;
};
/// The nearest hit along org + t dir, 0 <= t <= reach, whose triangle faces the way of n.
inline Side nearestFacing(const RayScene& scene, const glm::vec3& org, const glm::vec3& dir, const glm::vec3& n, float reach) {
    Side side;
    float from = 0.0f;
    for (int hop = 0; hop < kMaxRayHops; ++hop) {
        const RayScene::Hit h = scene.intersect(org, dir, from, reach);
        if (!h.hit) return side;
        if (glm::dot(h.normal, n) > 0.0f) {
            side.found = true;
            side.t = h.t;
            return side;
        }
        side.against = true;
        from = std::nextafter(h.t, reach); // past this triangle
    }
    return side;
}
} // namespace detail

/// The samples of every tile (row-major, s = 2^k[t] per side), in tile order.
/// `progress` (if set) receives the fraction of tiles done, from any thread, one call at a time,
/// every 2 %.
inline std::vector<std::vector<double>> extractSamples(const BaseSurface& base, const std::vector<int>& k,
                                                       const RayScene& dense, double diagonal,
                                                       const ExtractOptions& options = {}, ExtractReport* report = nullptr,
                                                       const std::function<void(double)>& progress = {}) {
    if (!(options.shell > 0.0) || !std::isfinite(options.shell)) throw ArgumentError("extraction: the shell must be > 0");
    const int n = static_cast<int>(k.size());
    std::vector<std::vector<double>> out(static_cast<std::size_t>(n));
    std::atomic<long> hits{0}, misses{0}, folds{0}, total{0};
    std::atomic<int> tilesDone{0};
    std::mutex progressMutex;
    const float shell = static_cast<float>(options.shell * diagonal);
    tbb::parallel_for(0, n, [&](int t) {
        const int s = 1 << k[static_cast<std::size_t>(t)];
        std::vector<double>& y = out[static_cast<std::size_t>(t)];
        y.assign(static_cast<std::size_t>(s * s), 0.0);
        if (base.isHole(t)) return;
        total += static_cast<long>(s) * s;
        long h = 0, m = 0, f = 0;
        for (int j = 0; j < s; ++j)
            for (int i = 0; i < s; ++i) {
                const BaseSample<double> b = base.evaluate<double>(t, (i + 0.5) / s, (j + 0.5) / s, false);
                const glm::dvec3 cr = glm::cross(b.du, b.dv);
                const double l = glm::length(cr);
                const glm::dvec3 nd = l > 0.0 ? cr / l : glm::dvec3(0.0);
                const glm::vec3 o(b.p), dir(nd);
                const detail::Side up = detail::nearestFacing(dense, o, dir, dir, shell);
                const detail::Side down = detail::nearestFacing(dense, o, -dir, dir, up.found ? up.t : shell);
                double d = 0.0;
                if (down.found) { // nearer than any facing hit upwards (its reach was cut at up.t)
                    d = -static_cast<double>(down.t);
                    ++h;
                } else if (up.found) {
                    d = static_cast<double>(up.t);
                    ++h;
                } else {
                    if (up.against || down.against) ++f;
                    else ++m;
                    const RayScene::Closest c = dense.closest(o);
                    d = c.found ? std::clamp(glm::dot(glm::dvec3(c.point) - b.p, nd), -static_cast<double>(shell),
                                             static_cast<double>(shell))
                                : 0.0;
                }
                y[static_cast<std::size_t>(j * s + i)] = d;
            }
        hits += h;
        misses += m;
        folds += f;
        if (progress) {
            const int done = ++tilesDone;
            if (done * 50 / n != (done - 1) * 50 / n) {
                const std::lock_guard<std::mutex> lock(progressMutex);
                progress(static_cast<double>(done) / n);
            }
        }
    });
    if (report) {
        report->hits = hits;
        report->misses = misses;
        report->foldovers = folds;
        report->samples = total;
        report->maxAbs = 0.0;
        for (const std::vector<double>& y : out)
            for (double d : y) report->maxAbs = std::max(report->maxAbs, std::abs(d));
    }
    return out;
}

/// Per-face tile sizes from the local detail (coarsestTileWithin for every tile, in
/// parallel): a smooth stretch of a scan gets small tiles, wrinkles keep the full size.
/// `samples` (at kMax, as extractSamples gives them) are replaced by those of the chosen
/// sizes; returns the sizes. All tiles must be quads' (one size per Ptex face, no
/// T-junctions: a baked base mesh is all quads).
inline std::vector<int> adaptiveTileSizes(std::vector<std::vector<double>>& samples, int kMax, double tolerance, int kMin = kMinTileLog2) {
    const int n = static_cast<int>(samples.size());
    std::vector<int> k(static_cast<std::size_t>(n), kMax);
    tbb::parallel_for(0, n, [&](int t) {
        k[static_cast<std::size_t>(t)] = coarsestTileWithin(samples[static_cast<std::size_t>(t)], kMax, tolerance, kMin);
    });
    return k;
}

/// A displacement source that returns the sample of the sub-patch holding (u, v): what the tile
/// fit asks for at the sub-patch centres, from samples taken beforehand (in parallel).
inline DisplacementFunction sampledSource(std::shared_ptr<const std::vector<std::vector<double>>> samples, std::vector<int> k) {
    return [samples, k = std::move(k)](int face, double u, double v) {
        const int s = 1 << k[static_cast<std::size_t>(face)];
        const int i = std::clamp(static_cast<int>(u * s), 0, s - 1), j = std::clamp(static_cast<int>(v * s), 0, s - 1);
        return (*samples)[static_cast<std::size_t>(face)][static_cast<std::size_t>(j * s + i)];
    };
}

} // namespace dispmap
