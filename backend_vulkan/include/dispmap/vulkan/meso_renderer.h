#pragma once
// dispmap::vulkan::MesoRenderer: per-pixel mesostructure ray marching in a fragment shader
// (shaders/meso/), headless. The base is the plane z = 0 (quads x quads quads, normal +z,
// tangent +x, bitangent +y, so tangent space is world space; the mesostructure tiles it every
// `tileSize` world units), or any surface given as a FrameMesh (`base`: the Catmull-Clark limit
// surface or a displaced surface, tessellated, with the mesostructure's texture coordinates
// and frame at every corner; surface/frame_mesh.h). The slab of `depth` world units lies
// below the base. Each pixel's view ray enters voxel space by Donnelly's normalisation
// (dmTangentToVoxel; on a base mesh in the pixel's interpolated frame, locally planar as
// Donnelly §8.3.1) and is marched by the chosen MesoTechnique; the technique and its knobs
// are specialisation constants, so only the chosen marcher is compiled into the pipeline. On
// a base mesh the pass has a depth buffer and writes the hit's depth; rays that miss show
// what lies behind. Shading: Lambert with the normal of the bilinear height field at the hit
// (or the normal map's, `normalMap`, and only then is its reading compiled in) and a checker
// albedo; a shadow ray through the DDM's shadow cones only when `shadows` is on
// (on a base mesh, a point whose base turns away from the light is in shadow). The colour is
// the albedo image's (`albedo`) at the hit, filtered over its mips, or a checker.
//
// Several mesostructures on one base mesh (MesoPart: maps, MesoLook and a range of triangles)
// are drawn in one pass, a pipeline each, into one depth buffer; MesoImage::part says which
// drew each pixel.
//
// The marchers are those of include/dispmap/meso/march.h, bit for bit on lavapipe: the
// per-pixel rays come back (rayOrigin, rayDir), and marchMeso<float> on them gives the same
// hits and iteration counts (tests/gpu/test_meso_gpu.cpp).
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/meso/march.h"
#include "dispmap/surface/frame_mesh.h"
#include "dispmap/vulkan/context.h"

namespace dispmap::vulkan {

struct MesoCamera {
    glm::dvec3 eye{1.2, -1.6, 1.1};
    glm::dvec3 target{0.0, 0.0, 0.0};
    glm::dvec3 up{0.0, 0.0, 1.0};
    double fovYDeg = 45.0;
};

/// What one mesostructure looks like: its marcher, shadows, slab depth, images and checker.
/// A scene of several mesostructures (MesoPart) gives each its own.
struct MesoLook {
    MesoTechnique technique;
    bool shadows = false;      ///< shadow rays through the DDM (needs maps built with ConeSet::shadow or isotropic)
    int shadowIterations = 64; ///< cap of the shadow march
    double shadowOffset = 0.05; ///< voxels along the height field's normal where shadow rays start
    double depth = 0.08;       ///< world units of the slab (z)
    /// The colour (meso/albedo.h: over one tile, with or without mips), sampled at the hit
    /// trilinearly at the pixel footprint's level; none: the checker below.
    std::shared_ptr<const MesoAlbedo> albedo;
    /// A tangent-space normal map over one tile (meso/albedo.h, e.g. normalMapFromHeights),
    /// sampled like the albedo: its normal (kern::dmNormalMapTangent, on the pixel's frame)
    /// shades instead of the height field's; the shadow ray still leaves along the height
    /// field's. None: the height field's normal.
    std::shared_ptr<const MesoAlbedo> normalMap;
    double normalScale = 1.0;  ///< multiplies the normal map's x and y (glTF's normalTexture.scale), |scale| <= kMaxNormalScale
    bool normalGreenUp = true; ///< green towards the image's top (OpenGL, glTF); false: towards its bottom (DirectX)
    double checkerVoxels = 8;  ///< checker period of the albedo, voxels (0: no checker)
};

/// The scene (image, camera, light, base) and the look of its one mesostructure (MesoLook).
struct MesoRenderOptions : MesoLook {
    int width = 256, height = 192;
    MesoCamera camera;
    glm::dvec3 lightDirection{0.5, 0.3, 0.8}; ///< towards the light (normalised here); z > 0 with shadows
    double tileSize = 0.5;     ///< world units of one tile of the mesostructure (x and y)
    double planeHalfSize = 1.0; ///< the plane spans [-h, h]^2
    int quads = 4;             ///< quads per side of the plane
    /// The base mesh instead of the plane (tileSize, planeHalfSize and quads then unused: its
    /// texture coordinates place the tiles). At most kMaxFrameCorners corners (frame_mesh.h),
    /// each frame solvable (frameIndependence >= kMinFrameIndependence, a unit normal) and
    /// its texture coordinates within kMaxFrameVoxel voxels of the origin.
    std::shared_ptr<const FrameMesh> base;
    /// The detail's own silhouettes on a curved base: a hit past the point where the view ray
    /// has left the shell through its top (the shell modelled around the pixel by the base's
    /// second fundamental form, kern::dmShellExit) is a miss, and so is a shadow ray's. Needs
    /// a base built with FrameMeshOptions::shape. Off: the locally planar slab everywhere.
    bool silhouettes = false;
    /// The view ray bent by the base's curvature (kern::dmMesoMarchDdmBent,
    /// kern::dmMesoMarchHeightBent, kern::dmMesoMarchDistanceBent): in the slab's own
    /// coordinates the straight world ray is a curve (kern::dmBentPoint: the shell's quadric
    /// along the ray, its level taken to the depth below the top as on a ball or a cylinder),
    /// marched as chords by the DDM (of a height field or a solid), sampled along the curve
    /// itself by relief mapping and POM and sphere-traced along it through the distance map, so
    /// the detail lies at its depth below the curved top rather than below the entry's tangent
    /// plane, and a ray bent back up leaves the shell by itself (silhouettes without the cut).
    /// Needs a base built with FrameMeshOptions::shape. Shadow rays stay straight (cut with
    /// `silhouettes`).
    bool bentRays = false;
    double ambient = 0.2;
    glm::dvec3 background{0.12, 0.13, 0.16};
    int frames = 3;            ///< timed frames (the GPU time is their median)
    int warmup = 1;            ///< untimed first frames (lavapipe compiles shaders at first use)
};

/// One of several mesostructures on a base mesh: its maps, its look, and how many of the
/// base's triangles it covers. The parts cover the base's triangles in order, part 0 the first
/// `triangles` (FrameMesh::groups, groupFrameMesh).
struct MesoPart {
    const MesoMaps* maps = nullptr; ///< uploaded by the renderer's constructor (not kept)
    MesoLook look;
    int triangles = 0;
};

struct MesoImage {
    int width = 0, height = 0;
    std::vector<std::uint8_t> rgba;          ///< 8-bit colour, row 0 at the top
    std::vector<std::uint32_t> iterations;   ///< view-ray iterations per pixel (0: background)
    std::vector<std::uint32_t> shadowIterations;
    std::vector<std::uint8_t> covered;       ///< 1 where the base covers the pixel (a base mesh: back faces and misses too, which write the far plane)
    std::vector<std::uint8_t> hit;           ///< 1 where the view ray hit (0: missed, or background)
    std::vector<std::uint8_t> cut;           ///< 1 where the march hit past the shell's exit (silhouettes): drawn as a miss
    std::vector<std::uint8_t> shadowed;      ///< 1 where the shadow ray hit the mesostructure (or the base turns away from the light)
    std::vector<glm::vec4> hitPoint;         ///< voxel-space hit point and t (bent rays: the point in the slab's coordinates where the detail was read; the world point is rayOrigin + rayDir t)
    std::vector<glm::vec3> rayOrigin, rayDir; ///< the pixel's view ray in voxel space (where covered)
    std::vector<std::uint8_t> part;          ///< which MesoPart drew the pixel (where covered; 0 with one mesostructure)
    std::vector<float> bend;                 ///< the view ray's bend (kern::dmShellBend) with bentRays, else 0
    std::vector<float> curve;                ///< and its curve (MesoBend::curve: kern::dmShellVoxels(shape).w), else 0
    double gpuMs = 0;                        ///< median GPU time of the timed frames (timestamps)
    int frames = 0;
};

/// Largest voxel coordinate a base mesh's texture coordinates may reach (|s| W, |t| H): 2^16,
/// where float still resolves 1/128 voxel (buildFrameMesh keeps every triangle's coordinates
/// within a few tiles of the origin).
inline constexpr double kMaxFrameVoxel = 65536.0;

/// The voxels per unit of the options' mapping for `maps`: on the plane (W / tileSize,
/// H / tileSize, L / depth) per world unit; on a base mesh (W, H, L / depth), voxels per
/// texture unit in s and t and per world unit along the normal.
glm::dvec3 mesoVoxelsPerUnit(const MesoMaps& maps, const MesoRenderOptions& options);
/// The same for one part of a scene: `look`'s depth, the scene's base or plane.
glm::dvec3 mesoVoxelsPerUnit(const MesoMaps& maps, const MesoLook& look, const MesoRenderOptions& scene);

class MesoRenderer {
  public:
    /// Uploads the maps and builds the pipeline of the options' technique. Keeps a reference
    /// to context (not to maps). ArgumentError for an image size out of [1, 4096], frames < 1,
    /// warm-up < 0, a bad technique (iterations or linear steps < 1), a camera at or below the
    /// plane, non-positive tile size / depth / plane, shadows without shadow cones or with a
    /// light at or below the horizon (the plane's rules); an empty or too large base mesh, or
    /// one with values that are not finite; an albedo or normal map whose words do not hold its
    /// levels, a normal-map scale that is not finite or beyond kMaxNormalScale.
    MesoRenderer(Context& context, const MesoMaps& maps, const MesoRenderOptions& options);
    /// Several mesostructures on the scene's base mesh in one pass (`scene`'s own look is not
    /// used): each part's maps and look, drawn over its range of triangles by a pipeline of its
    /// own technique, all into one depth buffer. The rules above for each part (the message
    /// naming it), maps that lack what its technique reads, and an ArgumentError without a base
    /// mesh, for no parts or more than 255, a part without maps, triangle counts that are
    /// negative or do not sum to the base's triangles, or, on a grouped base
    /// (FrameMesh::groups), that are not its groups'.
    MesoRenderer(Context& context, std::span<const MesoPart> parts, const MesoRenderOptions& scene);
    ~MesoRenderer();
    MesoRenderer(const MesoRenderer&) = delete;
    MesoRenderer& operator=(const MesoRenderer&) = delete;

    /// Renders warmup + frames frames and reads back the last.
    MesoImage render();

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// One technique in one call (what the examples' benchmark and scenes use): {gpuMs, image,
/// iterations, ...} in a MesoImage.
MesoImage renderMeso(Context& context, const MesoMaps& maps, const MesoRenderOptions& options);
/// Several mesostructures in one call (MesoRenderer's second constructor).
MesoImage renderMeso(Context& context, std::span<const MesoPart> parts, const MesoRenderOptions& scene);

/// The world-to-clip matrix of the options' camera (Vulkan clip space, y down, depth 0..1).
/// The far plane leaves room for the slab (`depth`); with several parts the renderer takes the
/// deepest part's depth in place of the scene's.
glm::dmat4 mesoViewProjection(const MesoRenderOptions& options);

} // namespace dispmap::vulkan
