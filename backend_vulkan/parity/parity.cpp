// The parity runner: input sets per kernel (exhaustive where the domain is small, dense grids
// with the exact edges and their neighbours, random and adversarial values otherwise), the
// C++ evaluation through the same dispatch text the shader runs, and the comparison.
#include "parity.h"
#include "meso_parity.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <limits>
#include <ostream>
#include <random>
#include <sstream>

#include "dispmap/surface/base_surface.h"
#include "dispmap/core/tileset.h"
#include "dispmap/vulkan/buffer.h"
#include "dispmap/vulkan/compute.h"
#include "dispmap/vulkan/context.h"
#include "kernels/parity_lod.h"
#include "kernels/parity_patch.h"
#include "kernels/parity_tile.h"
#include "parity_double_spv.h"
#include "parity_float_spv.h"
#include "parity_packed_spv.h"
#include "parity_patch_double_spv.h"
#include "parity_patch_float_spv.h"

namespace dispmap::parity {
namespace {

using glm::ivec4;

// ------------------------------------------------------------------------------------------
// The kernels, their numbers in the dispatch (parity_tile.h, parity_lod.h) and contracts.
enum class Scale : std::uint8_t {
    One,        // results of magnitude ~1 (basis values, parameters, weights, levels)
    Coeffs,     // max |c_ij| of the 9 coefficients (a, b, c.x)
    CoeffsS,    // max |c_ij| times the level size n.x
    Blend,      // max |value| of the two blended vectors
    Corners,    // max |corner| (b)
    Relative,   // the result itself
    Cross,      // max |e0.x e1.y|, |e0.y e1.x| (area term)
};
struct Kernel {
    int id;
    const char* name;
    bool doubleVariant;
    const char* contract; // "exact" or the inexact operations it uses
    double bound;         // ULP bound for an inexact kernel
    Scale scale;
    const char* unit;
};
// Bounds of the inexact kernels follow the SPIR-V precision Vulkan requires: x/y 2.5 ULP,
// sqrt as 1/inversesqrt (2 ULP here), log2 3 ULP outside [0.5, 2] and 2^-21 absolute inside
// (4 ULP of 1), exp2 3 + 2|x| ULP; the bounds add those of each operation on the path with a
// margin for the rounding of the exact operations around them.
constexpr Kernel kKernels[] = {
    {0, "dmBSpline2", true, "exact", 0, Scale::One, "ULP of max(|r|, 1)"},
    {1, "dmBSpline2D1", true, "exact", 0, Scale::One, "ULP of max(|r|, 1)"},
    {2, "dmBSpline2Derivs", true, "exact", 0, Scale::One, "ULP of max(|r|, 1)"},
    {3, "dmSubpatch", true, "exact", 0, Scale::One, "ULP of 1; cell exact"},
    {4, "dmBiquadratic", true, "exact", 0, Scale::Coeffs, "ULP of max|c|"},
    {5, "dmBiquadraticD1", true, "exact", 0, Scale::Coeffs, "ULP of max|c|"},
    {6, "dmBiquadraticD2", true, "exact", 0, Scale::Coeffs, "ULP of max|c|"},
    {7, "dmTileD1", true, "exact", 0, Scale::CoeffsS, "ULP of s max|c|"},
    {8, "dmBlendMips", true, "exact", 0, Scale::Blend, "ULP of max|x|"},
    {9, "dmBilerp", true, "exact", 0, Scale::Corners, "ULP of max|corner|"},
    {10, "dmMipOffset+dmTileFootprint", true, "exact", 0, Scale::One, "integer"},
    {11, "dmTileLog2", true, "exact", 0, Scale::One, "integer"},
    {12, "dmRecordTextureOffset+LocalOffset", true, "exact", 0, Scale::One, "integer"},
    {13, "dmRecordTileSize+Rotation", true, "exact", 0, Scale::One, "integer"},
    {14, "dmUnpackSizeDifferences", true, "exact", 0, Scale::One, "integer"},
    {15, "dmPackSizeDifferences", true, "exact", 0, Scale::One, "integer"},
    {16, "dmMaxResolution", true, "exact", 0, Scale::One, "ULP of max(|r|, 1)"},
    {17, "dmPackedLocate", true, "exact", 0, Scale::One, "ULP of 1; texel exact"},
    {18, "dmPatchToTile", true, "exact", 0, Scale::One, "ULP of 1"},
    {32, "dmTessFactorDistance", false, "sqrt, div", 8, Scale::Relative, "ULP of |r|"},
    {33, "dmTessAreaTerm", false, "exact", 0, Scale::Cross, "ULP of max|e0 e1|"},
    {34, "dmTessFactorArea", false, "sqrt", 4, Scale::Relative, "ULP of |r|"},
    {35, "dmTessFactorEdge", false, "exact", 0, Scale::Relative, "ULP of |r|"},
    {36, "dmClampTessFactor", false, "exact", 0, Scale::Relative, "ULP of |r|"},
    {37, "dmEdgeTessFactors", false, "exact", 0, Scale::Relative, "ULP of |r|"},
    {38, "dmInnerTessFactors", false, "exact", 0, Scale::Relative, "ULP of |r|"},
    {39, "dmSelectMips", false, "exact", 0, Scale::One, "ULP of 1; levels exact"},
    {40, "dmResolutionFromTessFactor", false, "log2", 4, Scale::One, "ULP of max(|r|, 1)"},
    {41, "dmMipLevelTexelRatio", false, "div, log2", 12, Scale::One, "ULP of max(|r|, 1)"},
    {42, "dmVertexResolutionTexelRatio", false, "exp2, div, log2", 16, Scale::One, "ULP of max(|r|, 1)"},
};
// Exact kernels on a device that contracts a*b + c: each fused operation may round once less;
// a few roundings of terms no larger than the scale.
constexpr double kFusedBound = 8;

template <class real> struct Batch {
    std::vector<real> args; // 12 per input
    std::vector<ivec4> ints;
    std::size_t size() const { return ints.size(); }
    void add(std::array<real, 12> a, ivec4 n) {
        args.insert(args.end(), a.begin(), a.end());
        ints.push_back(n);
    }
};

template <class real> real ulpOf(real x) {
    x = std::abs(x);
    return std::nextafter(x, std::numeric_limits<real>::infinity()) - x;
}

// Error of a GPU result y against the CPU result x in ULP of max(|x|, the kernel's scale),
// whose ULP is `unit`: 0 when the bits agree (or for +0 against -0), Inf when one is NaN.
template <class real> double ulpError(real x, real y, real unit) {
    if (std::memcmp(&x, &y, sizeof(real)) == 0 || x == y) return 0;
    if (std::isnan(x) || std::isnan(y)) return std::numeric_limits<double>::infinity();
    const real u = std::max(unit, ulpOf(x));
    return static_cast<double>(std::abs(x - y)) / static_cast<double>(u > 0 ? u : std::numeric_limits<real>::denorm_min());
}

// ------------------------------------------------------------------------------------------
// Inputs.
template <class real> struct Gen {
    std::mt19937_64 rng;
    explicit Gen(std::uint64_t seed) : rng(seed) {}
    real uniform(double lo, double hi) { return static_cast<real>(std::uniform_real_distribution<double>(lo, hi)(rng)); }
    int integer(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); }
    std::uint32_t word() { return static_cast<std::uint32_t>(rng()); }
    // Random sign, magnitude log-uniform in [10^lo, 10^hi].
    real logUniform(double lo, double hi) {
        double m = std::pow(10.0, std::uniform_real_distribution<double>(lo, hi)(rng));
        return static_cast<real>(integer(0, 1) ? m : -m);
    }
    real positive(double lo, double hi) { return std::abs(logUniform(lo, hi)); }
};

// Parameters in [0, 1] that a level of s sub-patches treats specially: 0, 1, every knot j/s,
// and the representable neighbours of each.
template <class real> std::vector<real> edgeParams(int s) {
    std::vector<real> v;
    for (int j = 0; j <= s; ++j) {
        real x = static_cast<real>(j) / static_cast<real>(s);
        v.push_back(x);
        if (j > 0) v.push_back(std::nextafter(x, real(0)));
        if (j < s) v.push_back(std::nextafter(x, real(1)));
    }
    v.push_back(std::numeric_limits<real>::denorm_min());
    return v;
}

// Fills `in` with about `budget` inputs for kernel `id`.
template <class real> void generate(int id, std::size_t budget, Gen<real>& g, Batch<real>& in) {
    const real z = 0;
    auto param = [&](std::size_t i, const std::vector<real>& edges) {
        return i < edges.size() ? edges[i] : g.uniform(0.0, 1.0);
    };
    switch (id) {
    case 0:
    case 1:
    case 2: { // t in [0, 1]: the knots' neighbours, a dense grid, random
        std::vector<real> edges = edgeParams<real>(1);
        const std::size_t grid = budget / 2;
        for (std::size_t i = 0; i < budget; ++i) {
            real t = i < edges.size() ? edges[i]
                     : i < grid       ? static_cast<real>(static_cast<double>(i) / static_cast<double>(grid))
                                      : g.uniform(0.0, 1.0);
            in.add({t, z, z, z, z, z, z, z, z, z, z, z}, ivec4(0));
        }
        break;
    }
    case 3: // (u, v) against every level size 1..256, with the knots and just outside [0, 1]
        for (int k = 0; k <= 8; ++k) {
            const int s = 1 << k;
            std::vector<real> e = edgeParams<real>(s);
            e.push_back(real(-0.25));
            e.push_back(real(1.25));
            const std::size_t n = std::max(e.size() * 4, budget / 9);
            for (std::size_t i = 0; i < n; ++i) {
                real u = param(i % (e.size() + 8), e), v = param((i * 7 + 3) % (e.size() + 8), e);
                in.add({u, v, z, z, z, z, z, z, z, z, z, z}, ivec4(s, 0, 0, 0));
            }
        }
        break;
    case 4:
    case 5:
    case 6:
    case 7: { // random coefficients over 6 decades, both signs; t at the edges and inside
        std::vector<real> e = edgeParams<real>(1);
        for (std::size_t i = 0; i < budget; ++i) {
            std::array<real, 12> a{};
            const bool flat = i % 17 == 0; // constant data: cancellation in the derivatives
            real c0 = g.logUniform(-3, 3);
            for (int j = 0; j < 9; ++j) a[static_cast<std::size_t>(j)] = flat ? c0 : g.logUniform(-3, 3);
            a[9] = param(i % (e.size() + 16), e);
            a[10] = param((i / 3) % (e.size() + 16), e);
            in.add(a, ivec4(1 << (i % 9), 0, 0, 0));
        }
        break;
    }
    case 8: { // blends at w = 0, 1, their neighbours and inside
        std::vector<real> e = edgeParams<real>(1);
        for (std::size_t i = 0; i < budget; ++i) {
            std::array<real, 12> a{};
            for (int j = 0; j < 6; ++j) a[static_cast<std::size_t>(j)] = g.logUniform(-3, 3);
            a[6] = param(i % (e.size() + 8), e);
            in.add(a, ivec4(0));
        }
        break;
    }
    case 9: { // corner values (integer differences as the tiles use them, and random)
        std::vector<real> e = edgeParams<real>(4);
        for (std::size_t i = 0; i < budget; ++i) {
            std::array<real, 12> a{};
            a[0] = param(i % (e.size() + 4), e);
            a[1] = param((i / (e.size() + 4)) % (e.size() + 4), e);
            for (int j = 4; j < 8; ++j)
                a[static_cast<std::size_t>(j)] = i % 2 ? static_cast<real>(g.integer(0, 7)) : g.logUniform(-3, 3);
            in.add(a, ivec4(0));
        }
        break;
    }
    case 10: // every k and level
        for (int k = 1; k <= 15; ++k)
            for (int m = 0; m < k; ++m) in.add({}, ivec4(k, m, 0, 0));
        break;
    case 11: // every size up to 2^16 + 1
        for (int s = 0; s <= 65537; ++s) in.add({}, ivec4(s, 0, 0, 0));
        break;
    case 12:
    case 13: // random record words and the extremes
        in.add({}, ivec4(0));
        in.add({}, ivec4(-1));
        for (std::size_t i = 0; i < budget; ++i) {
            ivec4 n;
            for (int j = 0; j < 4; ++j) n[j] = static_cast<int>(g.word());
            in.add({}, n);
        }
        break;
    case 14: // every combination of four differences 0..7, then random words
        for (int w = 0; w < 4096; ++w) {
            std::uint32_t word = 0;
            for (int c = 0; c < 4; ++c) word |= static_cast<std::uint32_t>((w >> (3 * c)) & 7) << (8 * c);
            in.add({}, ivec4(static_cast<int>(word), 0, 0, 0));
        }
        for (std::size_t i = 0; i < budget / 4; ++i) in.add({}, ivec4(static_cast<int>(g.word()), 0, 0, 0));
        break;
    case 15: // every combination of 0..15 per corner, then random (negative) values
        for (int w = 0; w < 65536; ++w) in.add({}, ivec4(w & 15, (w >> 4) & 15, (w >> 8) & 15, w >> 12));
        for (std::size_t i = 0; i < budget / 4; ++i)
            in.add({}, ivec4(g.integer(-300, 300), g.integer(-300, 300), g.integer(-300, 300), g.integer(-300, 300)));
        break;
    case 16: { // every k, every per-corner difference the format allows (0..k-1), (u, v) grid
        const real uvs[] = {real(0), std::numeric_limits<real>::denorm_min(), std::nextafter(real(0), real(1)),
                            real(0.25), real(0.5), std::nextafter(real(1), real(0)), real(1)};
        for (int k = 1; k <= 8; ++k) {
            int combos = k * k * k * k;
            for (int w = 0; w < combos; ++w) {
                int d[4] = {w % k, (w / k) % k, (w / (k * k)) % k, w / (k * k * k)};
                std::uint32_t word = 0;
                for (int c = 0; c < 4; ++c) word |= static_cast<std::uint32_t>(d[c]) << (8 * c);
                for (real u : uvs)
                    for (real v : uvs)
                        in.add({u, v, z, z, z, z, z, z, z, z, z, z}, ivec4(k, static_cast<int>(word), 0, 0));
            }
        }
        break;
    }
    case 17: // every k and level, the level's knots, random footprint offsets
        for (int k = 1; k <= 8; ++k) {
            for (int m = 0; m < k; ++m) {
                std::vector<real> e = edgeParams<real>((1 << k) >> m);
                const std::size_t n = std::max(e.size() * 2, budget / 36);
                for (std::size_t i = 0; i < n; ++i) {
                    std::uint32_t off = static_cast<std::uint32_t>(g.integer(0, 65000)) |
                                        static_cast<std::uint32_t>(g.integer(0, 65000)) << 16;
                    std::uint32_t size = static_cast<std::uint32_t>(1 << k) | static_cast<std::uint32_t>(g.integer(0, 3)) << 16;
                    in.add({param(i % (e.size() + 4), e), param((i * 5 + 1) % (e.size() + 4), e), static_cast<real>(m), z, z,
                            z, z, z, z, z, z, z},
                           ivec4(static_cast<int>(off), 0, static_cast<int>(size), 0));
                }
            }
        }
        break;
    case 18: // every rotation, depths 0..8, every local offset up to depth 3, random beyond
        for (int depth = 0; depth <= 8; ++depth) {
            const int side = 1 << depth;
            std::vector<real> e = edgeParams<real>(2);
            for (int rot = 0; rot < 4; ++rot) {
                const std::size_t n = depth <= 3 ? std::max<std::size_t>(static_cast<std::size_t>(side * side) * e.size(), budget / 36)
                                                 : budget / 36;
                for (std::size_t i = 0; i < n; ++i) {
                    int ox = depth <= 3 ? static_cast<int>(i) % side : g.integer(0, side - 1);
                    int oy = depth <= 3 ? (static_cast<int>(i) / side) % side : g.integer(0, side - 1);
                    in.add({param(i % (e.size() + 3), e), param((i / 3) % (e.size() + 3), e), z, z, z, z, z, z, z, z, z, z},
                           ivec4(ox, oy, depth, rot));
                }
            }
        }
        break;
    case 32: // eye and vertex over 8 decades, the eye at the vertex, tiny scale factors
        for (std::size_t i = 0; i < budget; ++i) {
            std::array<real, 12> a{};
            for (int j = 0; j < 3; ++j) a[static_cast<std::size_t>(j)] = g.logUniform(-4, 4);
            for (int j = 3; j < 6; ++j)
                a[static_cast<std::size_t>(j)] = i % 7 == 0 ? a[static_cast<std::size_t>(j - 3)] : g.logUniform(-4, 4);
            a[6] = g.positive(-6, 6);
            in.add(a, ivec4(0));
        }
        break;
    case 33: // screen-space edges, including (nearly) collinear pairs: cancellation
        for (std::size_t i = 0; i < budget; ++i) {
            real ax = g.logUniform(-3, 4), ay = g.logUniform(-3, 4);
            real s = g.logUniform(-2, 2);
            real bx = i % 3 == 0 ? ax * s : g.logUniform(-3, 4);
            real by = i % 3 == 0 ? ay * s : g.logUniform(-3, 4);
            in.add({ax, ay, bx, by, z, z, z, z, z, z, z, z}, ivec4(0));
        }
        break;
    case 34:
    case 35:
    case 36: // sums, lengths and factors over many decades; negative sums and factors below 1
        for (std::size_t i = 0; i < budget; ++i) {
            real x = i % 11 == 0 ? -g.positive(-3, 3) : g.positive(-8, 8);
            real c = id == 36 ? static_cast<real>(g.integer(1, 64)) : g.positive(-3, 3);
            in.add({x, c, z, z, z, z, z, z, z, z, z, z}, ivec4(0));
        }
        break;
    case 37:
    case 38: // corner / edge factors, equal neighbours
        for (std::size_t i = 0; i < budget; ++i) {
            std::array<real, 12> a{};
            for (int j = 0; j < 4; ++j)
                a[static_cast<std::size_t>(j)] = i % 5 == 0 ? real(8) : g.uniform(1.0, 64.0);
            in.add(a, ivec4(0));
        }
        break;
    case 39: { // rho over [-1, 10] densely with every integer and its neighbours, every k
        for (int k = 1; k <= 8; ++k) {
            for (std::size_t i = 0; i < budget / 8; ++i) {
                real rho;
                if (i < 12 * 3) {
                    real n = static_cast<real>(static_cast<int>(i / 3) - 1);
                    rho = i % 3 == 0 ? n : i % 3 == 1 ? std::nextafter(n, real(-20)) : std::nextafter(n, real(20));
                } else {
                    rho = g.uniform(-1.0, 10.0);
                }
                real maxRes = i % 4 == 0 ? static_cast<real>(g.integer(0, 9)) : g.uniform(0.0, 9.0);
                in.add({rho, maxRes, z, z, z, z, z, z, z, z, z, z}, ivec4(k, 0, 0, 0));
            }
        }
        break;
    }
    case 40:
    case 41:
    case 42: // factors over [0.1, 1e4]: powers of two, their neighbours, random
        for (std::size_t i = 0; i < budget; ++i) {
            real tf;
            if (i < 3 * 18) {
                real p = std::ldexp(real(1), static_cast<int>(i / 3) - 3);
                tf = i % 3 == 0 ? p : i % 3 == 1 ? std::nextafter(p, real(0)) : std::nextafter(p, real(1e9));
            } else {
                tf = g.positive(-1, 4);
            }
            int k = 1 + static_cast<int>(i % 8);
            real texels = std::ldexp(real(1), k);
            in.add({id == 41 ? texels : tf, tf, z, z, z, z, z, z, z, z, z, z}, ivec4(k, 0, 0, 0));
        }
        break;
    default:
        break;
    }
}

template <class real> real scaleOf(Scale s, const real* a, ivec4 n, const real* cpu) {
    auto maxAbs = [](const real* p, int count) {
        real m = 0;
        for (int i = 0; i < count; ++i) m = std::max(m, std::abs(p[i]));
        return m;
    };
    switch (s) {
    case Scale::One: return real(1);
    case Scale::Coeffs: return maxAbs(a, 9);
    case Scale::CoeffsS: return maxAbs(a, 9) * static_cast<real>(n.x);
    case Scale::Blend: return maxAbs(a, 6);
    case Scale::Corners: return maxAbs(a + 4, 4);
    case Scale::Relative: return maxAbs(cpu, 12);
    case Scale::Cross: return std::max(std::abs(a[0] * a[3]), std::abs(a[1] * a[2]));
    }
    return real(1);
}

template <class real> std::string describe(const real* a, ivec4 n) {
    std::ostringstream s;
    s << std::setprecision(std::numeric_limits<real>::max_digits10) << "a=(";
    for (int i = 0; i < 12; ++i) s << (i ? i % 4 == 0 ? "; " : ", " : "") << a[i];
    s << ") n=(" << n.x << ", " << n.y << ", " << n.z << ", " << n.w << ")";
    return s.str();
}

// The CPU side: the same dispatch text the shader runs.
template <class real> void evaluate(int id, const real* args, ivec4 n, real* out, ivec4& o) {
    using v4 = glm::vec<4, real>;
    v4 a(args[0], args[1], args[2], args[3]), b(args[4], args[5], args[6], args[7]), c(args[8], args[9], args[10], args[11]);
    v4 r(0), q(0), p(0);
    o = ivec4(0);
    if (id < 32) {
        kern::dmParityTile(id, a, b, c, n, r, q, p, o);
    } else if constexpr (std::is_same_v<real, float>) {
        kern::dmParityLod(id, a, b, n, r, o); // float only, as in the shader
    }
    for (int i = 0; i < 4; ++i) {
        out[i] = r[i];
        out[4 + i] = q[i];
        out[8 + i] = p[i];
    }
}

struct Push {
    std::int32_t kernel;
    std::uint32_t count;
    std::uint32_t rowStride;
};

constexpr std::size_t kChunk = 1u << 18; // inputs per dispatch: 12 MiB of double arguments

template <class real>
KernelResult runKernel(vulkan::Context& ctx, const vulkan::ComputePipeline& pipe, const Kernel& k, const Options& opt,
                       bool strict) {
    Gen<real> g(opt.seed + static_cast<std::uint64_t>(k.id) * 7919u + (sizeof(real) == 8 ? 1u : 0u));
    Batch<real> in;
    generate<real>(k.id, opt.inputs, g, in);
    KernelResult res;
    res.kernel = k.name;
    res.precision = sizeof(real) == 4 ? "float" : "double";
    res.contract = k.contract;
    res.unit = k.unit;
    const bool exact = std::string(k.contract) == "exact";
    res.bound = exact ? (strict ? 0.0 : kFusedBound) : k.bound;
    res.inputs = in.size();
    double sum = 0;
    std::size_t results = 0;
    const std::size_t chunk = std::min(kChunk, in.size());
    vulkan::Buffer args(ctx, chunk * 12 * sizeof(real)), ints(ctx, chunk * sizeof(ivec4));
    vulkan::Buffer outArgs(ctx, chunk * 12 * sizeof(real)), outInts(ctx, chunk * sizeof(ivec4));
    const vulkan::Buffer* bufs[] = {&args, &ints, &outArgs, &outInts};
    for (std::size_t begin = 0; begin < in.size(); begin += chunk) {
        const std::size_t count = std::min(chunk, in.size() - begin);
        args.upload(in.args.data() + begin * 12, count * 12 * sizeof(real));
        ints.upload(in.ints.data() + begin, count * sizeof(ivec4));
        const auto groups = static_cast<std::uint32_t>((count + 63) / 64);
        Push push{k.id, static_cast<std::uint32_t>(count), groups * 64u};
        res.gpuSeconds += ctx.dispatch(pipe, bufs, glm::uvec3(groups, 1, 1), &push, sizeof(push));
        const real* gpu = outArgs.as<const real>().data();
        const ivec4* gpuInts = outInts.as<const ivec4>().data();
        for (std::size_t i = 0; i < count; ++i) {
            const real* a = in.args.data() + (begin + i) * 12;
            const ivec4 n = in.ints[begin + i];
            real cpu[12];
            ivec4 o;
            evaluate<real>(k.id, a, n, cpu, o);
            const real unit = ulpOf(std::max(scaleOf<real>(k.scale, a, n, cpu), real(0)));
            double worst = 0;
            bool same = std::memcmp(&o, &gpuInts[i], sizeof(o)) == 0;
            if (!same) worst = std::numeric_limits<double>::infinity();
            for (int j = 0; j < 12; ++j) {
                const real x = cpu[j], y = gpu[i * 12 + static_cast<std::size_t>(j)];
                same = same && std::memcmp(&x, &y, sizeof(real)) == 0;
                worst = std::max(worst, ulpError(x, y, unit));
            }
            res.bitExact += same ? 1 : 0;
            sum += std::isfinite(worst) ? worst : 0;
            ++results;
            if (worst > res.maxUlp || (res.worstInput.empty() && worst > 0)) {
                res.maxUlp = worst;
                res.worstInput = describe(a, n);
            }
        }
    }
    res.meanUlp = results ? sum / static_cast<double>(results) : 0;
    return res;
}

// The renderer's lookup: a tile set with every tile size 1..8 (two of each, random data), every
// per-corner difference combination the sizes allow, every rotation, local offsets of refined
// patches, (u, v) on knots and edges, and resolutions across all levels.
KernelResult runPacked(vulkan::Context& ctx, const Options& opt, bool strict) {
    Gen<float> g(opt.seed ^ 0x9e3779b97f4a7c15ull);
    TileSet ts;
    for (int k = kMinTileLog2; k <= kMaxTileLog2; ++k) {
        for (int copy = 0; copy < 2; ++copy) {
            Tile t;
            t.k = k;
            for (int c = 0; c < 4; ++c) t.sizeDifferences[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(g.integer(0, k - 1));
            t.coefficients.resize(Tile::totalTexels(k));
            for (float& x : t.coefficients) x = g.logUniform(-2, 1);
            ts.tiles.push_back(std::move(t));
        }
    }
    PackedTiles packed = ts.pack();
    // Variants of every record: rotations and local offsets (depth below the tile).
    struct Query {
        glm::vec2 uv;
        float rho;
        std::int32_t record, depth, pad0, pad1, pad2;
    };
    static_assert(sizeof(Query) == 32);
    std::vector<PatchRecord> records;
    std::vector<Query> queries;
    std::vector<float> scale;
    const std::size_t perRecord = std::max<std::size_t>(opt.inputs / 64, 64);
    for (std::size_t t = 0; t < packed.records.size(); ++t) {
        float maxAbs = 0;
        for (float x : ts.tiles[t].coefficients) maxAbs = std::max(maxAbs, std::abs(x));
        for (int variant = 0; variant < 4; ++variant) {
            PatchRecord r = packed.records[t];
            r.rotation = static_cast<std::uint16_t>(variant);
            const int depth = variant; // 0..3 levels of refinement below the tile
            r.localDomainOffsetXY[0] = static_cast<std::uint16_t>(g.integer(0, (1 << depth) - 1));
            r.localDomainOffsetXY[1] = static_cast<std::uint16_t>(g.integer(0, (1 << depth) - 1));
            // Every combination of differences once per tile size, through the records.
            if (variant == 3) {
                const int k = ts.tiles[t].k;
                for (int c = 0; c < 4; ++c) r.tileSizeDifferences[c] = static_cast<std::uint8_t>(g.integer(0, k - 1));
            }
            const auto id = static_cast<std::int32_t>(records.size());
            records.push_back(r);
            std::vector<float> e = edgeParams<float>(ts.tiles[t].size() >> std::min(depth, ts.tiles[t].k));
            for (std::size_t i = 0; i < perRecord; ++i) {
                float u = i < e.size() * 2 ? e[i % e.size()] : g.uniform(0.0, 1.0);
                float v = i < e.size() * 2 ? e[(i / 2 + 1) % e.size()] : g.uniform(0.0, 1.0);
                float rho = i % 5 == 0 ? static_cast<float>(g.integer(0, 9)) : g.uniform(0.0, 9.0);
                queries.push_back({glm::vec2(u, v), rho, id, depth, 0, 0, 0});
                scale.push_back(maxAbs * static_cast<float>(ts.tiles[t].size()));
            }
        }
    }
    packed.records = records; // the variants replace the packer's records

    KernelResult res;
    res.kernel = "PackedTiles::sampleD1 (whole lookup)";
    res.precision = "float";
    res.contract = "exact";
    res.unit = "ULP of s max|c| of the tile";
    res.bound = strict ? 0.0 : kFusedBound;
    res.inputs = queries.size();

    static const std::uint32_t* spv = parity_packed_spv;
    vulkan::ComputePipeline pipe(ctx, std::span<const std::uint32_t>(spv, sizeof(parity_packed_spv) / 4), 4, 12);
    vulkan::Buffer texels(ctx, packed.texels.size() * sizeof(float));
    vulkan::Buffer recs(ctx, records.size() * sizeof(PatchRecord));
    vulkan::Buffer qs(ctx, queries.size() * sizeof(Query));
    vulkan::Buffer out(ctx, queries.size() * sizeof(glm::vec4));
    texels.upload(packed.texels.data(), packed.texels.size() * sizeof(float));
    recs.upload(records.data(), records.size() * sizeof(PatchRecord));
    qs.upload(queries.data(), queries.size() * sizeof(Query));
    const vulkan::Buffer* bufs[] = {&texels, &recs, &qs, &out};
    const auto count = static_cast<std::uint32_t>(queries.size());
    const std::uint32_t groupsX = std::min<std::uint32_t>((count + 63) / 64, 32768);
    const std::uint32_t groupsY = (count + groupsX * 64 - 1) / (groupsX * 64);
    struct {
        std::uint32_t count, rowStride;
        std::int32_t width;
    } push{count, groupsX * 64, packed.width};
    res.gpuSeconds = ctx.dispatch(pipe, bufs, glm::uvec3(groupsX, groupsY, 1), &push, sizeof(push));
    const glm::vec4* gpu = out.as<const glm::vec4>().data();
    double sum = 0;
    for (std::size_t i = 0; i < queries.size(); ++i) {
        const Query& q = queries[i];
        const glm::uvec4 w = recordWords(records[static_cast<std::size_t>(q.record)]);
        const glm::vec2 uv = kern::dmPatchToTile(q.uv, kern::dmRecordLocalOffset(w), q.depth, kern::dmRecordRotation(w));
        const glm::vec3 cpu = packed.sampleD1<float>(q.record, uv, q.rho);
        const float unit = ulpOf(scale[i]);
        double worst = 0;
        bool same = true;
        for (int j = 0; j < 3; ++j) {
            same = same && std::memcmp(&cpu[j], &gpu[i][j], sizeof(float)) == 0;
            worst = std::max(worst, ulpError(cpu[j], gpu[i][j], unit));
        }
        res.bitExact += same ? 1 : 0;
        sum += std::isfinite(worst) ? worst : 0;
        if (worst > res.maxUlp) {
            res.maxUlp = worst;
            std::ostringstream s;
            s << std::setprecision(9) << "record " << q.record << " (k=" << ts.tiles[static_cast<std::size_t>(q.record / 4)].k
              << ", rotation " << w.z / 65536u << ", depth " << q.depth << ") patch uv=(" << q.uv.x << ", " << q.uv.y
              << ") rho=" << q.rho;
            res.worstInput = s.str();
        }
    }
    res.meanUlp = sum / static_cast<double>(queries.size());
    return res;
}

// ------------------------------------------------------------------------------------------
// The base-surface patch kernels (kernels/patch.h, dispatch parity_patch.h, shader
// parity_patch.comp) on the PatchParams of real Far patch tables.

// A cube with two pentagons (N-gon sub-faces: NonQuadRoot patches; valence 3 and 5: end caps),
// open at the bottom (boundary masks) with a flap hanging from one bottom edge (sharp boundary
// corners of valence 2: corner masks), and one infinitely sharp crease (useInfSharpPatch:
// regular patches with boundary masks). Measured: 30 end caps, 22 masked regular patches (masks
// 1, 2, 4, 8, 6, 12), 124 unmasked ones, 100 NonQuadRoot, per end-cap type.
constexpr const char* kPatchMesh = "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
                                   "v 0 -1 1\nv -1 -2 -1.5\nv 1 -2 -1.5\n"
                                   "f 5 9 6 7 8\nf 1 2 6 9 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\nf 2 1 10 11\n"
                                   "t crease 2/1/0 6 7 10\nt interpolateboundary 1/0/0 1\n";

struct PatchParamInput {
    glm::uvec2 param;
    int cvCount;
};

// Every patch of the mesh's tables (Gregory and B-spline end caps, isolation 3), and PatchParams
// with every field at its extremes (decoding only).
std::vector<PatchParamInput> patchParams(bool extremes) {
    std::vector<PatchParamInput> out;
    const ControlMesh mesh = ControlMesh::fromObjText(kPatchMesh, "parity patch mesh");
    for (const bool gregory : {true, false}) {
        BaseSurfaceOptions o;
        o.isolationLevel = 3;
        o.gregoryEndCaps = gregory;
        const BaseSurface base(mesh, o);
        const Far::PatchTable& table = base.patchTable();
        for (int a = 0; a < table.GetNumPatchArrays(); ++a)
            for (int i = 0; i < table.GetNumPatches(a); ++i) {
                const Far::PatchParam p = table.GetPatchParam(a, i);
                out.push_back({glm::uvec2(p.field0, p.field1), table.GetPatchArrayDescriptor(a).GetNumControlVertices()});
            }
    }
    if (extremes)
        for (int k = 0; k < 16; ++k) {
            Far::PatchParam p;
            const bool hi = k & 1;
            p.Set(hi ? (1 << 28) - 1 : 0, static_cast<short>(hi ? 1023 : 0), static_cast<short>(k & 2 ? 1023 : 0),
                  static_cast<unsigned short>(k & 4 ? 10 : 1), (k & 8) != 0, static_cast<unsigned short>(k & 2 ? 31 : 0),
                  static_cast<unsigned short>(hi ? 15 : 0), (k & 4) != 0);
            out.push_back({glm::uvec2(p.field0, p.field1), k & 1 ? 20 : 16});
        }
    return out;
}

struct PatchKernel {
    int id;            // kernel number in parity_patch.h
    const char* name;
    int cvFilter;      // only parameters with this many control points (0: all)
    const char* contract;
    double bound;
    const char* unit;
};
// Gregory weights divide (the rational blend of the face points, 2.5 ULP in Vulkan); with the
// Bezier products around it a few ULP of the weight. The rest is polynomial or bit work.
constexpr PatchKernel kPatchKernels[] = {
    {0, "dmPatchBasis2 (B-spline)", 16, "exact", 0, "ULP of max(|w|, 2^(kL))"},
    {0, "dmPatchBasis2 (Gregory)", 20, "div", 8, "ULP of max(|w|, 2^(kL))"},
    {1, "dmPatchBasis1", 0, "div", 8, "ULP of max(|w|, 2^(kL))"},
    {2, "dmQuadTreeStep", 0, "exact", 0, "ULP of 1; quadrants exact"},
    {3, "dmPatchLocal+dmEndCapCornerWeights", 0, "exact", 0, "ULP of 1; decoding exact"},
};

template <class real>
KernelResult runPatch(vulkan::Context& ctx, const vulkan::ComputePipeline& pipe, const PatchKernel& k,
                      const std::vector<PatchParamInput>& params, const Options& opt, bool strict) {
    Gen<real> g(opt.seed + 104729u * static_cast<std::uint64_t>(k.id + k.cvFilter) + (sizeof(real) == 8 ? 1u : 0u));
    std::vector<PatchParamInput> ps;
    for (const PatchParamInput& p : params)
        if (k.cvFilter == 0 || p.cvCount == k.cvFilter) ps.push_back(p);
    // Inputs: per parameter the local (s, t) on the patch's corners, edges, centre and their
    // neighbours, then random; mapped to face (u, v) = ((s, t) + (U, V)) 2^-L in `real`.
    const std::vector<real> local = {real(0), std::ldexp(real(1), -10), std::nextafter(real(0.5), real(0)), real(0.5),
                                     std::nextafter(real(1), real(0)), real(1)};
    const std::size_t edgeInputs = ps.size() * local.size() * local.size();
    const std::size_t count = k.id == 3 ? ps.size() * 9 : std::max(opt.inputs / 8, k.id == 2 ? std::size_t(4096) : edgeInputs);
    std::vector<real> args;
    std::vector<ivec4> ints;
    std::vector<real> edges = edgeParams<real>(64);
    for (std::size_t i = 0; i < count; ++i) {
        const PatchParamInput& p = ps[i % ps.size()];
        real u, v;
        if (k.id == 2) {
            u = i < edges.size() * edges.size() ? edges[i % edges.size()] : g.uniform(0.0, 1.0);
            v = i < edges.size() * edges.size() ? edges[i / edges.size()] : g.uniform(0.0, 1.0);
        } else {
            const std::size_t j = i / ps.size();
            real s = i < edgeInputs ? local[j % local.size()] : g.uniform(0.0, 1.0);
            real t = i < edgeInputs ? local[j / local.size() % local.size()] : g.uniform(0.0, 1.0);
            const glm::ivec2 off = kern::dmPatchOffset(p.param);
            const real frac = std::ldexp(real(1), -kern::dmPatchDomainLevel(p.param));
            u = std::min((s + static_cast<real>(off.x)) * frac, real(1));
            v = std::min((t + static_cast<real>(off.y)) * frac, real(1));
        }
        args.push_back(u);
        args.push_back(v);
        ints.emplace_back(static_cast<int>(p.param.x), static_cast<int>(p.param.y), p.cvCount, 0);
    }

    KernelResult res;
    res.kernel = k.name;
    res.precision = sizeof(real) == 4 ? "float" : "double";
    res.contract = k.contract;
    res.unit = k.unit;
    const bool exact = std::string(k.contract) == "exact";
    res.bound = exact ? (strict ? 0.0 : kFusedBound) : k.bound;
    res.inputs = count;
    constexpr std::size_t kPatchChunk = 8192; // 120 results per input: 7.5 MiB of doubles
    const std::size_t chunk = std::min(kPatchChunk, count);
    vulkan::Buffer inArgs(ctx, chunk * 2 * sizeof(real)), inInts(ctx, chunk * sizeof(ivec4));
    vulkan::Buffer outArgs(ctx, chunk * 120 * sizeof(real)), outInts(ctx, chunk * sizeof(ivec4));
    const vulkan::Buffer* bufs[] = {&inArgs, &inInts, &outArgs, &outInts};
    double sum = 0;
    for (std::size_t begin = 0; begin < count; begin += chunk) {
        const std::size_t n = std::min(chunk, count - begin);
        inArgs.upload(args.data() + begin * 2, n * 2 * sizeof(real));
        inInts.upload(ints.data() + begin, n * sizeof(ivec4));
        const auto groups = static_cast<std::uint32_t>((n + 63) / 64);
        Push push{k.id, static_cast<std::uint32_t>(n), groups * 64u};
        res.gpuSeconds += ctx.dispatch(pipe, bufs, glm::uvec3(groups, 1, 1), &push, sizeof(push));
        const real* gpu = outArgs.as<const real>().data();
        const ivec4* gpuInts = outInts.as<const ivec4>().data();
        for (std::size_t i = 0; i < n; ++i) {
            const ivec4 in = ints[begin + i];
            const glm::uvec2 param(static_cast<std::uint32_t>(in.x), static_cast<std::uint32_t>(in.y));
            const glm::vec<2, real> uv(args[2 * (begin + i)], args[2 * (begin + i) + 1]);
            real cpu[120];
            ivec4 o;
            kern::dmParityPatch(k.id, param, in.z, uv, cpu, o);
            bool same = std::memcmp(&o, &gpuInts[i], sizeof(o)) == 0;
            double worst = same ? 0 : std::numeric_limits<double>::infinity();
            const int level = kern::dmPatchDomainLevel(param);
            for (int j = 0; j < 120; ++j) {
                const real x = cpu[j], y = gpu[i * 120 + static_cast<std::size_t>(j)];
                // Weights of derivative order m (w; wu, wv; wuu, wuv, wvv) carry 2^(mL).
                const int order = k.id <= 1 ? (j < 20 ? 0 : j < 60 ? 1 : 2) : 0;
                const real scale = std::ldexp(real(1), order * level);
                same = same && std::memcmp(&x, &y, sizeof(real)) == 0;
                worst = std::max(worst, ulpError(x, y, ulpOf(std::max(std::abs(x), scale))));
            }
            res.bitExact += same ? 1 : 0;
            sum += std::isfinite(worst) ? worst : 0;
            if (worst > res.maxUlp || (res.worstInput.empty() && worst > 0)) {
                res.maxUlp = worst;
                std::ostringstream s;
                s << std::setprecision(std::numeric_limits<real>::max_digits10) << "param=(0x" << std::hex << param.x << ", 0x"
                  << param.y << std::dec << ") cvCount=" << in.z << " uv=(" << uv.x << ", " << uv.y << ")";
                res.worstInput = s.str();
            }
        }
    }
    res.meanUlp = count ? sum / static_cast<double>(count) : 0;
    return res;
}

} // namespace

bool strictFor(const vulkan::Context& context, const Options& options) {
    if (options.strict >= 0) return options.strict == 1;
    return context.deviceName().find("llvmpipe") != std::string::npos;
}

std::vector<KernelResult> run(vulkan::Context& ctx, const Options& opt) {
    const bool strict = strictFor(ctx, opt);
    std::vector<KernelResult> results;
    vulkan::ComputePipeline floatPipe(ctx, std::span<const std::uint32_t>(parity_float_spv, sizeof(parity_float_spv) / 4), 4,
                                      sizeof(Push));
    for (const Kernel& k : kKernels)
        if (opt.filter.empty() || std::string(k.name).find(opt.filter) != std::string::npos)
            results.push_back(runKernel<float>(ctx, floatPipe, k, opt, strict));
    if (ctx.float64Enabled()) {
        vulkan::ComputePipeline doublePipe(
            ctx, std::span<const std::uint32_t>(parity_double_spv, sizeof(parity_double_spv) / 4), 4, sizeof(Push));
        for (const Kernel& k : kKernels)
            if (k.doubleVariant && (opt.filter.empty() || std::string(k.name).find(opt.filter) != std::string::npos))
                results.push_back(runKernel<double>(ctx, doublePipe, k, opt, strict));
    }
    if (opt.filter.empty() || std::string("PackedTiles::sampleD1").find(opt.filter) != std::string::npos)
        results.push_back(runPacked(ctx, opt, strict));
    // The base-surface patch kernels.
    std::vector<const PatchKernel*> patchKernels;
    for (const PatchKernel& k : kPatchKernels)
        if (opt.filter.empty() || std::string(k.name).find(opt.filter) != std::string::npos) patchKernels.push_back(&k);
    if (!patchKernels.empty()) {
        const std::vector<PatchParamInput> params = patchParams(false), decode = patchParams(true);
        vulkan::ComputePipeline pf(ctx, std::span<const std::uint32_t>(parity_patch_float_spv, sizeof(parity_patch_float_spv) / 4),
                                   4, sizeof(Push));
        for (const PatchKernel* k : patchKernels)
            results.push_back(runPatch<float>(ctx, pf, *k, k->id == 3 ? decode : params, opt, strict));
        if (ctx.float64Enabled()) {
            vulkan::ComputePipeline pd(
                ctx, std::span<const std::uint32_t>(parity_patch_double_spv, sizeof(parity_patch_double_spv) / 4), 4,
                sizeof(Push));
            for (const PatchKernel* k : patchKernels)
                results.push_back(runPatch<double>(ctx, pd, *k, k->id == 3 ? decode : params, opt, strict));
        }
    }
    // The mesostructure marchers (meso_parity.cpp).
    for (KernelResult& r : runMeso(ctx, opt)) results.push_back(std::move(r));
    return results;
}

void printTable(std::ostream& out, const std::vector<KernelResult>& results, const std::string& device, bool strict) {
    out << "CPU/GPU parity on " << device << " (exact kernels held to "
        << (strict ? "0 ULP: this device does not contract multiply-adds" : "8 ULP: the device may fuse multiply-adds")
        << ")\n";
    out << std::left << std::setw(40) << "kernel" << std::setw(8) << "prec" << std::right << std::setw(9) << "inputs"
        << std::setw(10) << "bit-exact" << std::setw(10) << "max err" << std::setw(10) << "mean err" << std::setw(7)
        << "bound" << std::setw(9) << "ns/in" << "  " << std::left << std::setw(17) << "contract" << std::setw(28)
        << "unit" << "verdict\n";
    double gpu = 0;
    for (const KernelResult& r : results) {
        std::ostringstream pct;
        pct << std::fixed << std::setprecision(r.bitExact == r.inputs ? 0 : 2)
            << 100.0 * static_cast<double>(r.bitExact) / static_cast<double>(std::max<std::size_t>(r.inputs, 1)) << "%";
        out << std::left << std::setw(40) << r.kernel << std::setw(8) << r.precision << std::right << std::setw(9) << r.inputs
            << std::setw(10) << pct.str() << std::setw(10) << std::setprecision(3) << r.maxUlp << std::setw(10)
            << std::setprecision(3) << r.meanUlp << std::setw(7) << r.bound << std::setw(9) << std::setprecision(3)
            << r.gpuSeconds * 1e9 / static_cast<double>(std::max<std::size_t>(r.inputs, 1)) << "  " << std::left
            << std::setw(17)
            << r.contract << std::setw(28) << r.unit << (r.ok() ? "ok" : "OVER BOUND") << "\n";
        gpu += r.gpuSeconds;
    }
    bool any = false;
    for (const KernelResult& r : results) {
        if (r.maxUlp == 0) continue;
        if (!any) out << "worst inputs:\n";
        any = true;
        out << "  " << r.kernel << " (" << r.precision << "): " << r.worstInput << "\n";
    }
    std::size_t inputs = 0;
    for (const KernelResult& r : results) inputs += r.inputs;
    out << inputs << " inputs, " << std::setprecision(3) << gpu * 1e3 << " ms of GPU time (timestamps)\n";
}

} // namespace dispmap::parity
