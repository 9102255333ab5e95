#pragma once
// dispmap::vulkan::SurfaceRenderer: the displaced Catmull-Clark surface drawn with hardware
// tessellation (Nießner & Loop 2013, §5.3, §5.4, §6), headless, into an offscreen colour,
// normal and depth target that is read back.
//
// One tessellation patch per Ptex face. The control shader computes the factors by the
// draw's method (§6.1) from the base vertices; the evaluation shader finds the OpenSubdiv
// Far patch containing (u, v) through the face's quadtree (PackedSurface), evaluates s and its
// derivatives with the patch-basis kernels, reads D from the packed tiles with mip selection
// (§6.2) and displaces; the fragment shader forms the normal per pixel from D's derivatives.
// Drawing whole Ptex faces, not the Far sub-patches as the paper does, keeps shared edges
// watertight without transition patches: both faces of an edge see the same edge factor, and
// a T-junction against an N-gon gets the even factor h on each half and 2h on the quad.
//
// Effects: the draw's effects (SurfaceDraw, surface/draw.h) become specialisation constants (shaders/render/common.glsl);
// an effect that is off is removed when the pipeline is created. `lean` builds the shaders
// without the optional effects at all, for the benchmark showing that off costs nothing.
// Only the pipelines the draw needs are created (the wireframe pipeline only with the
// wireframe effect); the baseline's textures are uploaded only for the baseline technique.
#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/surface/baseline.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/draw.h"
#include "dispmap/vulkan/context.h"

namespace dispmap::vulkan {

struct RendererOptions {
    /// Faces per draw call. Lavapipe runs one tessellated draw on one thread through a slow
    /// per-draw loop (docs/lavapipe.md), so big draws are split.
    int facesPerDraw = 16;
    /// Shaders built without accurate/auto normals, LOD and capture (the "not built" side of
    /// the effects benchmark). ArgumentError if the draw asks for one of those.
    bool lean = false;
    /// Room for this many vertices of the evaluation shader, read back by render() (tests);
    /// 0: the capture is not compiled in.
    std::uint32_t captureCapacity = 0;
};

/// A vertex the evaluation shader produced (capture on).
struct CapturedVertex {
    int face = 0;
    glm::vec2 uv{0};
    glm::vec3 position{0};
    float rho = 0; ///< resolution read (64 = finest, mips off)
};

struct RenderStats {
    double gpuMs = 0;            ///< median of the timed frames (timestamp queries)
    std::uint64_t patches = 0;   ///< tessellation control patches
    std::uint64_t tesInvocations = 0;
    std::uint64_t triangles = 0; ///< primitives reaching the clipper
    int frames = 0;
};

struct RenderedImage {
    int width = 0, height = 0;
    std::vector<std::uint8_t> rgba;   ///< 8-bit colour, row 0 at the top
    std::vector<glm::vec4> normals;   ///< world normal (xyz) and 1 where the surface covers the pixel, else 0
    std::vector<float> depth;         ///< depth buffer [0, 1], 1 = background
    std::vector<CapturedVertex> captured;
    std::uint32_t capturedTotal = 0;  ///< vertices the shader produced (may exceed the capacity)
    RenderStats stats;
};

class SurfaceRenderer {
  public:
    /// Uploads `surface` (its base surface and tiles) and, for the baseline technique, `atlas`
    /// (ArgumentError if it is missing then), and builds the pipelines `draw` asks for.
    /// Keeps references to context and surface. ArgumentError for a draw checkSurfaceDraw
    /// rejects; VulkanError if the device lacks tessellation shaders (or vertex-pipeline
    /// stores with capture on).
    SurfaceRenderer(Context& context, const SurfaceDraw& draw, const DisplacedSurface& surface,
                  const BaselineAtlas* atlas = nullptr, RendererOptions options = {});
    ~SurfaceRenderer();
    SurfaceRenderer(const SurfaceRenderer&) = delete;
    SurfaceRenderer& operator=(const SurfaceRenderer&) = delete;

    /// Renders `frames` times (the first `warmup` untimed: lavapipe compiles shaders at first
    /// use) and reads back the last. GPU time is the median over the timed frames.
    RenderedImage render(int frames = 1, int warmup = 1);

    /// Changes the factor value (uniform factor or method constant c) for the next render.
    void setTessValue(double value);
    /// Moves the camera for the next render (ArgumentError for a camera checkSurfaceDraw rejects).
    void setCamera(const Camera& camera);

    /// The world-to-clip matrix of the current camera (Vulkan clip space, y down, depth 0..1).
    glm::dmat4 viewProjection() const;
    /// Bytes uploaded for the surface (patch table, quadtree, tiles, topology; baseline maps).
    std::size_t uploadedBytes() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// The world-to-clip matrix of `camera` for a width x height image (Vulkan conventions).
glm::dmat4 viewProjection(const Camera& camera, int width, int height);

/// Image differences of `test` against `reference` (same size): RMS of the 8-bit colour
/// difference over all pixels, mean and max angle between normals (degrees) where both cover
/// the pixel, and the share of pixels covered by exactly one of them.
struct ImageError {
    double rmsColor = 0, meanNormalDeg = 0, maxNormalDeg = 0, coverageMismatch = 0;
};
ImageError compareImages(const RenderedImage& test, const RenderedImage& reference);

} // namespace dispmap::vulkan
