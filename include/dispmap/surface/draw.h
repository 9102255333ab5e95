#pragma once
// What a renderer needs to draw a displaced surface, as plain structures: the technique and
// effects, the camera, the lights and the image. The Vulkan renderer (dispmap/vulkan/
// renderer.h) takes these; a scene file (scene/scene.h) is one way to fill them, an engine
// fills them itself. Only the effects named here are compiled into the renderer's pipelines.
//
// Tessellation factors (Nießner & Loop 2013, §6.1; kernels/lod.h): Uniform uses `tessValue`
// as the factor; Distance, ScreenEdge and ScreenArea use it as the constant c of
// dmTessFactorDistance, dmTessFactorEdge and dmTessFactorArea; all are clamped to maxFactor.
#include <charconv>
#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/core/error.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/tessellator.h"

namespace dispmap {

/// How the surface is drawn: the base surface alone, displaced by our tiles, or the
/// traditional baseline (a UV height texture plus a tangent-space normal map, baseline.h).
enum class Technique { Base, Displaced, Baseline };
inline const char* toString(Technique t) {
    return t == Technique::Base ? "base" : t == Technique::Displaced ? "displaced" : "baseline";
}

/// Tessellation factors (§6.1): uniform, by distance to the eye, by projected edge length, or
/// by projected area.
enum class TessMethod { Uniform, Distance, ScreenEdge, ScreenArea };
inline const char* toString(TessMethod m) {
    return m == TessMethod::Uniform ? "uniform" : m == TessMethod::Distance ? "distance"
                                              : m == TessMethod::ScreenEdge ? "edge"
                                                                            : "area";
}

/// Largest width or height of a drawn image, and most lights.
inline constexpr int kMaxImageSize = 4096;
inline constexpr int kMaxLights = 8;

/// Smallest near plane: the smallest normal float. The renderer's projection goes to the GPU
/// as floats; a near plane below it is 0 or a subnormal there, and the depth divides by it.
inline constexpr double kMinNearPlane = 1.1754943508222875e-38; // std::numeric_limits<float>::min()
/// Largest far / near. The depth buffer is D32_SFLOAT with depth = f/(f-n) (1 - n/z): near the
/// far plane the depth's 24-bit mantissa resolves z only to about (far/near) 2^-24 of z, 60 %
/// at 1e7, so beyond that the depth test orders nothing.
inline constexpr double kMaxDepthRatio = 1e7;
/// Smallest vertical field of view, degrees. At 4096 rows a pixel then spans 4e-8 rad, float's
/// relative precision: below it neighbouring pixels see the same float positions (and at 1e-300
/// the projection's 1/tan(fov/2) is not a float at all).
inline constexpr double kMinFovDeg = 0.01;
/// Largest magnitude of a camera coordinate, light colour, ambient term or tessellation value.
/// They go to the GPU as floats (largest 3.4e38), which square and sum them: 1e18 keeps the
/// squares of coordinates and the sums over kMaxLights lights finite.
inline constexpr double kMaxDrawValue = 1e18;

struct Camera {
    glm::dvec3 eye{0, 0, 5}, target{0}, up{0, 1, 0};
    double fovYDeg = 40;     ///< vertical field of view, [kMinFovDeg, 180) degrees
    double nearPlane = 0.05; ///< >= kMinNearPlane
    double farPlane = 100;   ///< > nearPlane, at most kMaxDepthRatio nearPlane
};

struct Light {
    glm::dvec3 direction{0, 0, 1}; ///< towards the light, unit length
    glm::dvec3 color{1};           ///< >= 0 per channel
};

/// Where the renderer's tile lookup reads the packed texels: a storage buffer (gathers), or a
/// sampled image read with texelFetch (what engines and the paper use; the texture cache
/// serves it).
enum class TexelPath { Buffer, Image };

inline const char* toString(TexelPath p) { return p == TexelPath::Buffer ? "buffer" : "image"; }

/// The effects of a draw; each one that is off is left out of the pipelines.
struct SurfaceEffects {
    Technique technique = Technique::Displaced;
    NormalMode normals = NormalMode::Approximate; ///< approximate | accurate | auto
    double autoToleranceDeg = 2;                  ///< auto normals: accepted error, [0, 90] degrees
    MipSelection lod = MipSelection::TessFactor;  ///< off | tess factor | texel ratio
    TessMethod tessMethod = TessMethod::Uniform;
    double tessValue = 8;  ///< uniform: the factor; distance/edge/area: the constant c; > 0
    double maxFactor = 64; ///< clamp of the factors, [1, 64]
    Spacing spacing = Spacing::FractionalEven;
    bool wireframe = false;
    /// The tiles' texels on the GPU: float, or half floats (half the memory; D rounded to ~3
    /// digits, and the CPU mirror is PackedTiles::useHalf), from a buffer or an image.
    TexelFormat texelFormat = TexelFormat::Float;
    TexelPath texelPath = TexelPath::Buffer;
};

/// Everything about one draw of a surface except the surface: the image, camera, lighting and
/// effects. The renderers validate it (checkSurfaceDraw: ArgumentError naming the value).
struct SurfaceDraw {
    Camera camera;
    std::vector<Light> lights{Light{}}; ///< 0..kMaxLights
    double ambient = 0.15;               ///< >= 0
    glm::dvec3 albedo{0.8, 0.78, 0.74};  ///< [0, 1] per channel
    glm::dvec3 background{0.0, 0.0, 0.0}; ///< [0, 1] per channel
    int width = 320, height = 240;       ///< 1..kMaxImageSize each
    SurfaceEffects effects;
};

/// A value of a draw out of its range: `key` names it as a scene file does ("camera.near",
/// "resolution[0]", "lights[1].color[2]", "effects.tessellation.max"; scene/scene.h), so that the
/// scene reader and the renderers report the same rule, `why` says what is wrong
/// ("0 is out of range (must be > 0)").
struct DrawProblem {
    std::string key, why;
};

namespace detail {
// The shortest text that reads back as x ("0.1", "1e+300", "65"), as JSON writes numbers.
inline std::string drawNumber(double x) {
    char buf[32];
    const auto r = std::to_chars(buf, buf + sizeof buf, x);
    return std::string(buf, r.ptr);
}
// Why x is outside [lo, hi] (an end open where the flag says), or "" if it is inside; also
// for NaN ("nan is out of range (must be >= 0)") and infinities.
inline std::string outOfRange(double x, double lo, double hi, bool loOpen = false, bool hiOpen = false) {
    if (loOpen ? !(x > lo) : !(x >= lo))
        return drawNumber(x) + " is out of range (must be " + (loOpen ? "> " : ">= ") + drawNumber(lo) + ")";
    if (hiOpen ? !(x < hi) : !(x <= hi))
        return drawNumber(x) + " is out of range (must be " + (hiOpen ? "< " : "<= ") + drawNumber(hi) + ")";
    return {};
}
// Checks values one by one: keeps the first problem found and says whether each value is fine.
struct DrawChecker {
    std::optional<DrawProblem> problem;
    bool range(const std::string& key, double x, double lo, double hi, bool loOpen = false, bool hiOpen = false) {
        if (problem) return false;
        std::string why = outOfRange(x, lo, hi, loOpen, hiOpen);
        if (why.empty()) return true;
        problem = DrawProblem{key, std::move(why)};
        return false;
    }
    bool range3(const std::string& key, const glm::dvec3& v, double lo, double hi) {
        for (int i = 0; i < 3; ++i)
            if (!range(key + "[" + std::to_string(i) + "]", v[i], lo, hi)) return false;
        return true;
    }
    bool fail(const std::string& key, std::string why) {
        if (!problem) problem = DrawProblem{key, std::move(why)};
        return false;
    }
};
} // namespace detail

/// The first value of a camera out of range, or none: coordinates beyond +-kMaxDrawValue (or
/// not finite), eye = target, up zero or parallel to the view direction, a field of view
/// outside [kMinFovDeg, 180), near <= 0 or below kMinNearPlane, far <= near, or far / near
/// above kMaxDepthRatio.
inline std::optional<DrawProblem> cameraProblem(const Camera& c) {
    detail::DrawChecker k;
    if (!k.range3("camera.eye", c.eye, -kMaxDrawValue, kMaxDrawValue) ||
        !k.range3("camera.target", c.target, -kMaxDrawValue, kMaxDrawValue) ||
        !k.range3("camera.up", c.up, -kMaxDrawValue, kMaxDrawValue))
        return k.problem;
    const glm::dvec3 view = c.target - c.eye;
    const double lv = glm::length(view), lu = glm::length(c.up);
    if (!(lv > 0.0)) return DrawProblem{"camera", "eye and target are the same point"};
    if (!(lu > 0.0)) return DrawProblem{"camera.up", "is the zero vector"};
    if (!(glm::length(glm::cross(view / lv, c.up / lu)) > 1e-6))
        return DrawProblem{"camera.up", "is parallel to the view direction (target - eye)"};
    if (!k.range("camera.fovY", c.fovYDeg, 0.0, 180.0, true, true)) return k.problem;
    if (c.fovYDeg < kMinFovDeg)
        return DrawProblem{"camera.fovY", detail::drawNumber(c.fovYDeg) + " degrees is below " + detail::drawNumber(kMinFovDeg) +
                                              " (a pixel would span less than float's precision)"};
    if (!k.range("camera.near", c.nearPlane, 0.0, kMaxDrawValue, true)) return k.problem;
    if (c.nearPlane < kMinNearPlane)
        return DrawProblem{"camera.near", detail::drawNumber(c.nearPlane) + " is below " + detail::drawNumber(kMinNearPlane) +
                                              ", the smallest normal float (the projection divides by it on the GPU)"};
    if (!(c.farPlane > c.nearPlane) || !std::isfinite(c.farPlane))
        return DrawProblem{"camera.far", "must be greater than camera.near (" + detail::drawNumber(c.nearPlane) + ") and finite"};
    if (c.farPlane / c.nearPlane > kMaxDepthRatio)
        return DrawProblem{"camera.far", "far / near = " + detail::drawNumber(c.farPlane / c.nearPlane) + " exceeds " +
                                             detail::drawNumber(kMaxDepthRatio) +
                                             ", beyond which the depth buffer orders nothing: raise camera.near or lower camera.far"};
    return std::nullopt;
}

/// The first value of a draw out of range, or none: an image size outside [1, kMaxImageSize],
/// more than kMaxLights lights, a zero or non-finite light direction, light colours or ambient
/// outside [0, kMaxDrawValue], albedo and background outside [0, 1], effect values out of range
/// (tessValue in (0, kMaxDrawValue], maxFactor in [1, 64], auto tolerance in [0, 90]), or what
/// cameraProblem finds. Checked in the order a scene file lists them.
inline std::optional<DrawProblem> surfaceDrawProblem(const SurfaceDraw& d) {
    detail::DrawChecker k;
    if (auto p = cameraProblem(d.camera)) return p;
    if (d.lights.size() > static_cast<std::size_t>(kMaxLights))
        return DrawProblem{"lights", std::to_string(d.lights.size()) + " lights, at most " + std::to_string(kMaxLights)};
    for (std::size_t i = 0; i < d.lights.size(); ++i) {
        const std::string key = "lights[" + std::to_string(i) + "]";
        const Light& l = d.lights[i];
        if (!k.range3(key + ".direction", l.direction, -kMaxDrawValue, kMaxDrawValue)) return k.problem;
        if (!(glm::length(l.direction) > 0.0)) return DrawProblem{key + ".direction", "is the zero vector"};
        if (!k.range3(key + ".color", l.color, 0.0, kMaxDrawValue)) return k.problem;
    }
    const auto size = [&](const char* key, int v) {
        if (v >= 1 && v <= kMaxImageSize) return true;
        return k.fail(key, std::to_string(v) + " is out of range [1, " + std::to_string(kMaxImageSize) + "] (image size " +
                               std::to_string(d.width) + " x " + std::to_string(d.height) + ")");
    };
    const SurfaceEffects& e = d.effects;
    if (!k.range("ambient", d.ambient, 0.0, kMaxDrawValue) || !k.range3("albedo", d.albedo, 0.0, 1.0) ||
        !k.range3("background", d.background, 0.0, 1.0) || !size("resolution[0]", d.width) || !size("resolution[1]", d.height) ||
        !k.range("effects.autoTolerance", e.autoToleranceDeg, 0.0, 90.0) ||
        !k.range("effects.tessellation.value", e.tessValue, 0.0, kMaxDrawValue, true) ||
        !k.range("effects.tessellation.max", e.maxFactor, 1.0, 64.0))
        return k.problem;
    return std::nullopt;
}

/// Throws ArgumentError "<key>: <why>" for the value cameraProblem finds.
inline void checkCamera(const Camera& c) {
    if (const std::optional<DrawProblem> p = cameraProblem(c)) throw ArgumentError(p->key + ": " + p->why);
}

/// Throws ArgumentError "<key>: <why>" for the value surfaceDrawProblem finds (the key as a
/// scene file names it: "resolution[0]: 0 is out of range [1, 4096] (image size 0 x 240)").
inline void checkSurfaceDraw(const SurfaceDraw& d) {
    if (const std::optional<DrawProblem> p = surfaceDrawProblem(d)) throw ArgumentError(p->key + ": " + p->why);
}

} // namespace dispmap
