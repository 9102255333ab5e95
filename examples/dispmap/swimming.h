#pragma once
// Swimming: how far the tessellated displaced surface moves while a continuous tessellation
// factor changes, with and without mip selection (the texel-ratio rule; Nießner & Loop 2013, §6.2).
//
// A uniform factor T sweeps [tMin, tMax] in steps dT under FractionalEven spacing, so every
// tessellation vertex slides continuously over the surface. With D read at the finest level a
// sliding vertex samples every bump it crosses and the piecewise-linear surface "swims"; with
// mips, D is read at the resolution the factor can represent (rho = log2 TF, or the texel-ratio rule's
// M = log2(L/T) + 1), so what a vertex samples varies slowly.
//
// Measure. A fixed set of sample points x = (face, u, v), drawn once (seeded, uniform over the
// non-hole faces). For each T, P_T(x) is the position at parameter x on the tessellation (the
// triangle of x's face covering (u, v), barycentric interpolation; TriangleLocator). The swim
// speed is |P_T(x) - P_{T+dT}(x)| / dT (length units per unit of factor); a row reports its
// maximum and RMS over all x and steps. The accuracy cost of mips is |P_T(x) - f(x)| against
// the true surface f at the finest level, mean and max over all x and T. A first row
// measures the base surface alone (D = 0): the swimming of the piecewise-linear s, the floor no
// mip rule can go below.
//
// Reading it: P_T(x) is continuous in T except where the ring zipper changes its triangulation
// (an edge point passes an inner point, which happens where edge and inner spacings differ:
// at quad/N-gon T-junctions, or for non-uniform factors); such a flip moves P_T(x) by about
// the non-planarity of one quad, so the max swim (and, less, the RMS) grows like 1/dT with
// those jumps. Compare rows at the same dT; the RMS is the headline.
//
// Errors: ArgumentError for a sweep that is empty or not finite (tMin < 1, tMax <= tMin,
// dT <= 0, more than 100000 steps), fewer than 1 sample, a surface whose faces are all holes;
// FileError when the CSV cannot be written.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <ostream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "dispmap/surface/tessellator.h"

namespace dispmap {

struct SwimOptions {
    double tMin = 2, tMax = 16, dT = 0.125; ///< the sweep of the uniform factor
    int samples = 1024;                     ///< sample points x
    std::uint32_t seed = 4;                 ///< of the sample points
    double maxFactor = 64;
    /// The settings compared, one row each.
    std::vector<MipSelection> settings = {MipSelection::Off, MipSelection::TessFactor, MipSelection::TexelRatio};
    /// Also a first row for the base surface alone (D = 0, same tile sizes): the swimming of
    /// the piecewise-linear approximation of s itself, which no mip selection removes.
    bool baseline = true;
};

struct SwimRow {
    std::string setting;           ///< "no mips (finest D)", ...
    MipSelection mips = MipSelection::Off;
    bool baseline = false;         ///< the D = 0 row
    double tMin = 0, tMax = 0, dT = 0;
    int tessellations = 0;
    int samples = 0;
    double maxSwim = 0, rmsSwim = 0;     ///< |P_T(x) - P_{T+dT}(x)| / dT
    double meanError = 0, maxError = 0; ///< |P_T(x) - f(x)| against the finest surface
    double seconds = 0;                  ///< tessellation + location time of the row
};

inline std::string swimSettingName(MipSelection m) {
    switch (m) {
    case MipSelection::Off: return "no mips (finest D)";
    case MipSelection::TessFactor: return "mips: rho = log2 TF (6.2)";
    default: return "mips: texel ratio M = log2(L/T)+1";
    }
}

/// Fixed random points (face, u, v) on the faces that are not holes, and the displaced surface
/// f there (finest level): what a tessellation is measured against.
struct SurfaceProbe {
    std::vector<int> faces;
    std::vector<glm::dvec2> uvs;
    std::vector<glm::dvec3> truth;
};

/// `samples` points drawn with `seed`. Throws ArgumentError for samples < 1 or a surface whose
/// faces are all holes.
inline SurfaceProbe probeSurface(const DisplacedSurface& surface, int samples, std::uint32_t seed) {
    if (samples < 1) throw ArgumentError("a surface probe needs at least one sample point");
    const BaseSurface& base = surface.base();
    std::vector<int> faces;
    for (int f = 0; f < base.faceCount(); ++f)
        if (!base.isHole(f)) faces.push_back(f);
    if (faces.empty()) throw ArgumentError("surface probe: every face is a hole");
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    SurfaceProbe p;
    for (int i = 0; i < samples; ++i) {
        p.faces.push_back(faces[static_cast<std::size_t>(rng() % faces.size())]);
        p.uvs.emplace_back(U(rng), U(rng));
        p.truth.push_back(surface.evaluate<double>(p.faces.back(), p.uvs.back().x, p.uvs.back().y, NormalMode::Approximate).position);
    }
    return p;
}

/// Sweeps the factor and measures swimming and accuracy per setting (see the header).
inline std::vector<SwimRow> measureSwimming(const DisplacedSurface& surface, const SwimOptions& o = {}) {
    if (!std::isfinite(o.tMin) || !std::isfinite(o.tMax) || !std::isfinite(o.dT) || o.tMin < 1.0 || o.tMax <= o.tMin ||
        !(o.dT > 0.0) || (o.tMax - o.tMin) / o.dT > 100000.0)
        throw ArgumentError("swim sweep [" + std::to_string(o.tMin) + ", " + std::to_string(o.tMax) + "] step " +
                            std::to_string(o.dT) + " is invalid: need 1 <= tMin < tMax, dT > 0, at most 1e5 steps");
    const BaseSurface& base = surface.base();
    const SurfaceProbe probe = probeSurface(surface, o.samples, o.seed);
    const std::vector<int>& sf = probe.faces;
    const std::vector<glm::dvec2>& suv = probe.uvs;
    const std::vector<glm::dvec3>& truth = probe.truth;
    std::vector<glm::dvec3> truthBase(sf.size());
    for (std::size_t i = 0; i < sf.size(); ++i) truthBase[i] = base.evaluate<double>(sf[i], suv[i].x, suv[i].y, false).p;
    const int steps = static_cast<int>(std::floor((o.tMax - o.tMin) / o.dT + 1e-9));

    // The baseline: the same tiles with every coefficient 0.
    TileSet zeroTiles = surface.tiles();
    for (Tile& t : zeroTiles.tiles) std::fill(t.coefficients.begin(), t.coefficients.end(), 0.0f);
    const DisplacedSurface zero(base, zeroTiles, surface.options());
    std::vector<std::pair<MipSelection, bool>> settings;
    if (o.baseline) settings.emplace_back(MipSelection::Off, true);
    for (MipSelection m : o.settings) settings.emplace_back(m, false);

    std::vector<SwimRow> rows;
    for (const auto& [mips, isBaseline] : settings) {
        const DisplacedSurface& ds = isBaseline ? zero : surface;
        const auto t0 = std::chrono::steady_clock::now();
        SwimRow r;
        r.setting = isBaseline ? "base surface only (D = 0)" : swimSettingName(mips);
        r.mips = mips;
        r.baseline = isBaseline;
        r.tMin = o.tMin;
        r.tMax = o.tMin + steps * o.dT;
        r.dT = o.dT;
        r.samples = o.samples;
        TessellateOptions to;
        to.spacing = Spacing::FractionalEven;
        to.maxFactor = o.maxFactor;
        to.mips = mips;
        std::vector<glm::dvec3> prev, cur(sf.size());
        double sumSq = 0, sumErr = 0;
        long swimCount = 0, errCount = 0;
        for (int s = 0; s <= steps; ++s) {
            const double T = o.tMin + s * o.dT;
            const TriangleMesh mesh = tessellate(ds, uniformTessFactors(base, T), to);
            const TriangleLocator loc(mesh, base.faceCount());
            for (std::size_t i = 0; i < sf.size(); ++i) {
                cur[i] = loc.position(sf[i], suv[i]);
                const double err = glm::length(cur[i] - (isBaseline ? truthBase[i] : truth[i]));
                sumErr += err;
                r.maxError = std::max(r.maxError, err);
                ++errCount;
                if (!prev.empty()) {
                    const double speed = glm::length(cur[i] - prev[i]) / o.dT;
                    r.maxSwim = std::max(r.maxSwim, speed);
                    sumSq += speed * speed;
                    ++swimCount;
                }
            }
            prev = cur;
            ++r.tessellations;
        }
        r.rmsSwim = swimCount > 0 ? std::sqrt(sumSq / double(swimCount)) : 0.0;
        r.meanError = sumErr / double(errCount);
        r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        rows.push_back(r);
    }
    return rows;
}

/// Prints the rows as a text table (RMS swim relative to the row without mips, or the first
/// row) and, if `csvPath` is not empty, writes them as CSV (atomically). Throws FileError
/// naming the path.
inline void printSwimTable(std::ostream& out, const std::vector<SwimRow>& rows, const std::string& csvPath) {
    out << "  setting                          T range      steps   max swim    RMS swim  vs no mips   mean err    max "
           "err   time s\n";
    std::ostringstream csv;
    csv << "setting,t_min,t_max,dt,tessellations,samples,max_swim,rms_swim,rms_vs_no_mips,mean_error,max_error,seconds\n";
    double reference = rows.empty() ? 0.0 : rows.front().rmsSwim;
    for (const SwimRow& r : rows)
        if (!r.baseline && r.mips == MipSelection::Off) {
            reference = r.rmsSwim;
            break;
        }
    for (const SwimRow& r : rows) {
        const double ratio = reference > 0 ? r.rmsSwim / reference : 0.0;
        std::ostringstream range;
        range << r.tMin << ".." << r.tMax;
        out << "  " << std::left << std::setw(33) << r.setting << std::setw(13) << range.str() << std::right
            << std::setw(5) << r.tessellations - 1 << std::scientific << std::setprecision(3) << std::setw(11)
            << r.maxSwim << std::setw(12) << r.rmsSwim << std::fixed << std::setprecision(3) << std::setw(10) << ratio
            << std::scientific << std::setprecision(3) << std::setw(12) << r.meanError << std::setw(12) << r.maxError
            << std::fixed << std::setprecision(2) << std::setw(9) << r.seconds << "\n"
            << std::defaultfloat;
        csv << '"' << r.setting << "\"," << r.tMin << "," << r.tMax << "," << r.dT << "," << r.tessellations << "," << r.samples
            << "," << r.maxSwim << "," << r.rmsSwim << "," << ratio << "," << r.meanError << "," << r.maxError << ","
            << r.seconds << "\n";
    }
    if (!csvPath.empty()) {
        const std::string s = csv.str();
        detail::writeFileAtomically(csvPath, std::vector<unsigned char>(s.begin(), s.end()), "CSV table");
    }
}

} // namespace dispmap
