#pragma once
// What a renderer needs to draw a displaced surface, as plain structures: the technique and
// effects, the camera, the lights and the image. The Vulkan renderer (dispmap/vulkan/
// renderer.h) takes these; a scene file (scene/scene.h) is one way to fill them, an engine
// fills them itself. Only the effects named here are compiled into the renderer's pipelines.
//
// Tessellation factors (Nießner & Loop 2013, §6.1; kernels/lod.h): Uniform uses `tessValue`
// as the factor; Distance, ScreenEdge and ScreenArea use it as the constant c of
// dmTessFactorDistance, dmTessFactorEdge and dmTessFactorArea; all are clamped to maxFactor.
#include <cmath>
#include <string>
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

struct Camera {
    glm::dvec3 eye{0, 0, 5}, target{0}, up{0, 1, 0};
    double fovYDeg = 40;     ///< vertical field of view, (0, 180) degrees
    double nearPlane = 0.05; ///< > 0
    double farPlane = 100;   ///< > nearPlane
};

struct Light {
    glm::dvec3 direction{0, 0, 1}; ///< towards the light, unit length
    glm::dvec3 color{1};           ///< >= 0 per channel
};

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
};

/// Everything about one draw of a surface except the surface: the image, camera, lighting and
/// effects. The renderers validate it (ArgumentError naming the value).
struct SurfaceDraw {
    Camera camera;
    std::vector<Light> lights{Light{}}; ///< 0..kMaxLights
    double ambient = 0.15;               ///< >= 0
    glm::dvec3 albedo{0.8, 0.78, 0.74};  ///< [0, 1] per channel
    glm::dvec3 background{0.0, 0.0, 0.0}; ///< [0, 1] per channel
    int width = 320, height = 240;       ///< 1..kMaxImageSize each
    SurfaceEffects effects;
};

namespace detail {
inline bool finite3(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
inline bool inUnit3(const glm::dvec3& v) {
    return finite3(v) && v.x >= 0 && v.y >= 0 && v.z >= 0 && v.x <= 1 && v.y <= 1 && v.z <= 1;
}
} // namespace detail

/// Throws ArgumentError naming the field for a camera that cannot form a view: non-finite
/// values, eye = target, up parallel to the view direction, a field of view outside (0, 180)
/// degrees, near <= 0 or far <= near, or far / near beyond 1e7 (a 24-bit depth buffer
/// resolves nothing at that ratio).
inline void checkCamera(const Camera& c) {
    if (!detail::finite3(c.eye) || !detail::finite3(c.target) || !detail::finite3(c.up))
        throw ArgumentError("camera: eye, target and up must be finite");
    const glm::dvec3 view = c.target - c.eye;
    if (glm::length(view) <= 0 || !std::isfinite(glm::length(view))) throw ArgumentError("camera: eye equals target");
    if (glm::length(glm::cross(glm::normalize(view), c.up)) <= 1e-9 * glm::length(c.up))
        throw ArgumentError("camera: up is zero or parallel to the view direction");
    if (!(c.fovYDeg > 0 && c.fovYDeg < 180)) throw ArgumentError("camera: field of view " + std::to_string(c.fovYDeg) + " not in (0, 180) degrees");
    if (!(c.nearPlane > 0 && std::isfinite(c.nearPlane) && c.farPlane > c.nearPlane && std::isfinite(c.farPlane)))
        throw ArgumentError("camera: near " + std::to_string(c.nearPlane) + " and far " + std::to_string(c.farPlane) +
                            " must be finite with 0 < near < far");
    if (c.farPlane / c.nearPlane > 1e7)
        throw ArgumentError("camera: far / near = " + std::to_string(c.farPlane / c.nearPlane) + " exceeds 1e7");
}

/// Throws ArgumentError naming the field for a draw no renderer can honour: an image size
/// outside [1, kMaxImageSize], more than kMaxLights lights, non-finite or negative light
/// colours, a zero light direction, colours outside [0, 1], a negative ambient term, effect
/// values out of range (tessValue > 0, maxFactor in [1, 64], auto tolerance in [0, 90]), or a
/// camera checkCamera rejects.
inline void checkSurfaceDraw(const SurfaceDraw& d) {
    if (d.width < 1 || d.height < 1 || d.width > kMaxImageSize || d.height > kMaxImageSize)
        throw ArgumentError("image size " + std::to_string(d.width) + " x " + std::to_string(d.height) + " out of range [1, " +
                            std::to_string(kMaxImageSize) + "]");
    checkCamera(d.camera);
    if (d.lights.size() > static_cast<std::size_t>(kMaxLights))
        throw ArgumentError(std::to_string(d.lights.size()) + " lights, at most " + std::to_string(kMaxLights));
    for (const Light& l : d.lights) {
        if (!detail::finite3(l.direction) || glm::length(l.direction) <= 0) throw ArgumentError("light direction must be finite and non-zero");
        if (!detail::finite3(l.color) || l.color.x < 0 || l.color.y < 0 || l.color.z < 0)
            throw ArgumentError("light colour must be finite and >= 0");
    }
    if (!(d.ambient >= 0 && std::isfinite(d.ambient))) throw ArgumentError("ambient must be finite and >= 0");
    if (!detail::inUnit3(d.albedo) || !detail::inUnit3(d.background)) throw ArgumentError("albedo and background must be in [0, 1]");
    const SurfaceEffects& e = d.effects;
    if (!(e.tessValue > 0 && std::isfinite(e.tessValue))) throw ArgumentError("tessellation value must be finite and > 0");
    if (!(e.maxFactor >= 1 && e.maxFactor <= 64)) throw ArgumentError("maximum tessellation factor " + std::to_string(e.maxFactor) + " not in [1, 64]");
    if (!(e.autoToleranceDeg >= 0 && e.autoToleranceDeg <= 90)) throw ArgumentError("auto-normal tolerance not in [0, 90] degrees");
}

} // namespace dispmap
