// dispmap kernel prelude (C++ side).
//
// Every kernel in include/dispmap/kernels/ is written once, between the markers
//     // dispmap:glsl-begin      and      // dispmap:glsl-end
// (or `// dispmap:glsl-begin double` where GLSL should also get a double variant), and that
// text is at the same time C++ over GLM and GLSL 4.50. The generator (cmake/glslgen.cpp,
// output in shaders/generated/) copies the marked text verbatim and refuses what is outside
// the subset; all language differences live in this prelude and in its GLSL twin, which the
// generator writes as prelude.glsl:
//
//   spelling          C++ (this file)                       GLSL
//   DM_FUNC           inline                                (empty)
//   DM_TFUNC          template <typename real> inline       (empty)
//   DM_OUT(T)         T&                                    out T
//   DM_INOUT(T)       T&                                    inout T
//   DM_OUT_ARRAY(T)   T  (the array parameter decays to T*)  out T
//   real              the template parameter (float/double) #define real float (double variant: double,
//                                                          behind DM_ENABLE_DOUBLE)
//   rvec2..4, rmat3   glm::vec<N, real>, glm::mat<3,3,real> vec2..4, mat3 (double: dvec2.., dmat3)
//
// Rules of the subset (docs/design.md): free functions with a `dm` prefix; scalar, vector and
// matrix types only; no pointers, references outside DM_OUT/DM_INOUT, default arguments,
// recursion, swizzles, brace initialisation or struct constructors; literals written as
// real(0.5) so that they mean the same at both precisions. A DM_TFUNC must take at least
// one `real`-typed argument so that C++ deduces the precision. Kernels have no error path:
// callers validate; kernels clamp their parameters into the domain instead.
//
// The rvec/rmat macros are defined by this header and removed again by prelude_end.h at
// the end of every kernel header, so they never leak into user code. (A template's
// tokens are fixed when it is parsed, so undefining afterwards is safe.)

#ifndef DISPMAP_KERNELS_PRELUDE_ONCE
#define DISPMAP_KERNELS_PRELUDE_ONCE
#include <cstdint>
#include <glm/glm.hpp>

#define DM_FUNC inline
#define DM_TFUNC template <typename real> inline
#define DM_OUT(T) T&
#define DM_INOUT(T) T&
// An array the kernel fills: `DM_OUT_ARRAY(real) w[20]` (after OSD_OUT_ARRAY of OpenSubdiv's
// osd/patchBasis.h). GLSL copies it out on return, C++ writes through the decayed pointer:
// a kernel writes every element it promises and never reads one before writing it.
#define DM_OUT_ARRAY(T) T

namespace dispmap::kern {
// GLSL names resolve to GLM inside the kernel namespace, so <cmath> never wins overload
// resolution for a kernel.
using glm::abs;
using glm::ceil;
using glm::clamp;
using glm::cross;
using glm::dot;
using glm::exp2;
using glm::floor;
using glm::ivec2;
using glm::ivec4;
using glm::length;
using glm::log2;
using glm::max;
using glm::min;
using glm::mix;
using glm::sqrt;
using glm::uvec2;
using glm::uvec4;
using uint = std::uint32_t;
} // namespace dispmap::kern
#endif

#define rvec2 glm::vec<2, real, glm::defaultp>
#define rvec3 glm::vec<3, real, glm::defaultp>
#define rvec4 glm::vec<4, real, glm::defaultp>
#define rmat3 glm::mat<3, 3, real, glm::defaultp>
