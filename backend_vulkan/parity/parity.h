#pragma once
// CPU/GPU parity of every kernel (docs/design.md, "Kernels written once"): each kernel runs over
// a large set of inputs in a compute shader and in C++, and the results are compared under
// the kernel's stated precision contract.
//
// Precision contract (README, "The GLSL mirror"):
//  * exact kernels (polynomials, integer and bit work, floor/clamp/min/max): bit for bit on a
//    device that does not contract a*b + c into a fused multiply-add. Lavapipe does not
//    (measured; the C++ build uses -ffp-contract=off); Vulkan allows contraction, so on
//    other devices the bound is a few ULP of the kernel's scale (`fusedBound`).
//  * kernels with sqrt, division or log2: within the precision Vulkan guarantees for those
//    operations (SPIR-V precision appendix), never assumed exact.
// Errors are in ULP of max(|cpu result|, scale), where the scale is the magnitude of the
// kernel's terms (e.g. max |c_ij| for the biquadratic; 1 for values in [0, 1]), because an
// ULP of a result that cancels to near zero says nothing about the arithmetic.
#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

namespace dispmap::vulkan {
class Context;
}

namespace dispmap::parity {

struct Options {
    /// Inputs per kernel (the kernel's generator rounds to its exhaustive sets).
    std::size_t inputs = 1u << 18;
    std::uint64_t seed = 2026;
    /// Require bit-exact results for exact kernels. Default: when the device is lavapipe.
    int strict = -1; // -1 auto, 0 off, 1 on
    /// Only kernels whose name contains this text (empty: all).
    std::string filter;
    /// Rays per mesostructure marcher row (meso_parity.h): each is marched on the CPU too.
    std::size_t mesoRays = 1u << 14;
};

/// One kernel at one precision.
struct KernelResult {
    std::string kernel;      ///< e.g. "dmBiquadraticD1"
    std::string precision;   ///< "float" or "double"
    std::string contract;    ///< "exact" or e.g. "sqrt, div"
    std::size_t inputs = 0;
    std::size_t bitExact = 0; ///< inputs whose every result matched bit for bit
    double maxUlp = 0;       ///< worst error over all results, ULP of max(|cpu|, scale)
    double meanUlp = 0;
    double bound = 0;        ///< the bound maxUlp was held to
    std::string unit;        ///< what the scale is
    std::string worstInput;  ///< the input of maxUlp, printed in full
    double gpuSeconds = 0;   ///< summed timestamp time of the dispatches
    /// The marchers on a device that does not round like the CPU (not strict): a ray's decisions
    /// (hit, iteration count, the solid's triangle) may go the other way where an intermediate
    /// lands within a few ULP of a threshold, so the bound is on the hit (|t| in voxels) and
    /// holds for all but allowedOver of the inputs. Zero everywhere else: every input in bound.
    std::size_t over = 0;   ///< inputs over the bound
    double allowedOver = 0; ///< the share of the inputs that may be over it
    bool ok() const {
        return allowedOver > 0 ? static_cast<double>(over) <= allowedOver * static_cast<double>(inputs) : maxUlp <= bound;
    }
};

/// Runs every kernel (float, and double where the device has shaderFloat64), the packed
/// displacement lookup (PackedTiles::sampleD1 against shaders/parity_packed.comp) and the
/// base-surface patch kernels on the PatchParams of real Far patch tables
/// (shaders/parity_patch.comp), and the mesostructure marchers ("march ..." rows,
/// meso_parity.h: shaders/meso/march.glsl against meso_march.h on the same rays).
std::vector<KernelResult> run(vulkan::Context& context, const Options& options);

/// The table: kernel, precision, inputs, bit-exact share, max / mean error, bound, GPU time per
/// input (timestamps; includes loading and storing the arguments), verdict,
/// and below it the worst input of every kernel whose error is not zero.
void printTable(std::ostream& out, const std::vector<KernelResult>& results, const std::string& device, bool strict);

/// Whether `options` asks for the strict contract on this device (lavapipe: yes).
bool strictFor(const vulkan::Context& context, const Options& options);

} // namespace dispmap::parity
