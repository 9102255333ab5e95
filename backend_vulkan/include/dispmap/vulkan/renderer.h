#pragma once
// dispmap::vulkan::SurfaceRenderer: the displaced Catmull-Clark surface drawn with hardware
// tessellation (Nießner & Loop 2013, §5.3, §5.4, §6), either headless into its own offscreen
// colour, normal and depth targets that are read back (render()), or recorded into the
// caller's command buffer and dynamic-rendering instance with the caller's attachment formats
// (RendererOptions::target; recordUpdate() outside, recordDraw() inside the rendering). render()
// records the same two calls into its own targets.
//
// Animation (§4.1): after BaseSurface::setControlPoints, updateControlPoints() re-reads the
// refined points, the corner limit normals and the base vertices' limit positions; they are
// written with the next recordUpdate (or render()); nothing else is rebuilt.
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
#include <optional>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/surface/baseline.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/draw.h"
#include "dispmap/vulkan/context.h"

namespace dispmap::vulkan {

/// Formats of the caller's attachments (dynamic rendering). normal = VK_FORMAT_UNDEFINED: no normal attachment (the fragment shader variant without that output is used).
struct TargetFormats { VkFormat color = VK_FORMAT_B8G8R8A8_UNORM; VkFormat normal = VK_FORMAT_UNDEFINED; VkFormat depth = VK_FORMAT_D32_SFLOAT; };

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
    /// Empty: the renderer owns offscreen targets (render()). Set: it draws into the caller's attachments of these formats (recordUpdate / recordDraw); render() then throws ArgumentError.
    std::optional<TargetFormats> target;
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
    /// rejects, or target formats without a colour format or with a depth format that is not
    /// one; VulkanError if the context has not enabled tessellationShader,
    /// vertexPipelineStoresAndAtomics (the evaluation shader declares the writable capture
    /// buffer) or dynamic rendering (or fillModeNonSolid for the wireframe, independentBlend
    /// for the wireframe with a normal attachment), or the device cannot render to the target
    /// formats.
    SurfaceRenderer(Context& context, const SurfaceDraw& draw, const DisplacedSurface& surface,
                  const BaselineAtlas* atlas = nullptr, RendererOptions options = {});
    /// Waits for the device to be idle (frames recorded into the caller's command buffers may
    /// still run), then destroys the renderer's buffers, images and pipelines.
    ~SurfaceRenderer();
    SurfaceRenderer(const SurfaceRenderer&) = delete;
    SurfaceRenderer& operator=(const SurfaceRenderer&) = delete;

    /// Renders warmup + frames times (the first `warmup` untimed: lavapipe compiles shaders at
    /// first use, a GPU raises its clocks under load) and reads back the last. GPU time is the
    /// median over the timed frames. Each frame is recordUpdate + recordDraw into the
    /// renderer's own targets (colour R8G8B8A8_UNORM, normal R32G32B32A32_SFLOAT, depth
    /// D32_SFLOAT, at the current image size), submitted and waited for. ArgumentError for
    /// frames < 1 or warmup < 0, or with RendererOptions::target set.
    RenderedImage render(int frames = 1, int warmup = 1);

    /// Outside any render pass / rendering instance: writes this frame's parameters (camera, factors, lights) and any pending geometry into the renderer's buffers with vkCmdUpdateBuffer (so several frames may be in flight) and the barriers the draw needs.
    /// The command buffer must be on the context's device and a queue of its queue family that
    /// supports graphics; the barriers are global memory barriers (earlier shader reads before
    /// the writes, the writes before this frame's shader reads).
    void recordUpdate(VkCommandBuffer cmd);
    /// Inside the caller's vkCmdBeginRendering whose attachments have the TargetFormats given: sets viewport and scissor to the draw's size, binds and draws. The caller owns layouts, clears and barriers of its attachments. Depth: 0 near, 1 far, compare LESS.
    void recordDraw(VkCommandBuffer cmd);
    /// The image size the next frames are drawn at (screen-space factors and the viewport); ArgumentError outside [1, kMaxImageSize].
    void setImageSize(int width, int height);
    /// After surface.base().setControlPoints(...): re-reads the refined points, corner limit normals and base-vertex limit positions (nothing else is rebuilt) and uploads them with the next recordUpdate (or render()).
    /// The next recordUpdate writes them once (the command buffer it records into must be
    /// submitted); later frames see them in queue order. Per-face choices made from the shape
    /// at creation stay (auto normals: DisplacedSurface's per-face choice; the baseline's baked
    /// atlas). ArgumentError if the point or face counts differ from those at creation.
    void updateControlPoints();

    /// Edits (§5): after the surface's tiles changed in place (TileFitter::refit returns the
    /// tiles it rewrote), writes those tiles' footprints of the packed texture with the next
    /// recordUpdate (or render()); nothing else is re-packed or uploaded. The tiles keep their
    /// sizes. ArgumentError for a tile id out of range or a tile whose size changed.
    void updateTiles(const std::vector<int>& tiles);

    /// Changes the factor value (uniform factor or method constant c) for the next frame
    /// (written by recordUpdate).
    void setTessValue(double value);
    /// Moves the camera for the next frame (ArgumentError for a camera checkSurfaceDraw rejects).
    void setCamera(const Camera& camera);

    /// The world-to-clip matrix of the current camera and image size (Vulkan clip space, y
    /// down, depth 0..1).
    glm::dmat4 viewProjection() const;
    /// The current image size (SurfaceDraw::width/height, then setImageSize).
    int width() const;
    int height() const;
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

/// Background pixels not connected to the image border through background: seen whole, a
/// closed surface of genus 0 has none, so they are holes inside its silhouette, i.e. cracks.
int enclosedBackground(const RenderedImage& im);

/// Pixels covered in `reference` where `test` sees through that surface: background there, or
/// a view depth more than `depthGap` (world units) behind the reference's. Both images must
/// have been rendered with `camera` (its near and far planes turn depth back into distance).
/// Cracks in `test` that `reference` does not have, wherever the surface behind them is.
int seeThroughPixels(const RenderedImage& test, const RenderedImage& reference, const Camera& camera, double depthGap);

} // namespace dispmap::vulkan
