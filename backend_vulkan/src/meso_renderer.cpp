// MesoRenderer: the maps' buffers, five offscreen colour targets (colour, hit, ray origin, ray
// direction, counts; plus depth on a base mesh) drawn with dynamic rendering, the graphics
// pipeline of one technique (specialisation constants), frames with timestamps and the
// read-back (gpu_objects.h).
#include "dispmap/vulkan/meso_renderer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>

#include "dispmap/surface/draw.h"
#include "dispmap/vulkan/buffer.h"
#include "dispmap/vulkan/meso_maps.h"
#include "gpu_objects.h"

// SPIR-V of shaders/meso/ (NoContraction on every float operation: backend_vulkan/tools/spirv_exact.cpp).
#include "meso_base_vert_spv.h"
#include "meso_frag_spv.h"
#include "meso_vert_spv.h"

namespace dispmap::vulkan {

using namespace detail;

namespace {

struct GpuMesoParams { // shaders/meso/common.glsl
    glm::mat4 viewProj;
    glm::vec4 eye, light, voxelsPerUnit, plane, background;
    glm::ivec4 dims0, dims1, dims2;
    glm::vec4 tol;
};
static_assert(sizeof(GpuMesoParams) == 64 + 5 * 16 + 3 * 16 + 16);

struct GpuFrameVertex { // shaders/meso/common.glsl, DmFrameVertex
    glm::vec4 position, pS, pT, normal, shape;
};
static_assert(sizeof(GpuFrameVertex) == 80 && kMaxFrameCorners * sizeof(GpuFrameVertex) <= (std::size_t{1} << 27));

constexpr std::uint32_t kTargets = 5;
const VkFormat kFormats[kTargets] = {VK_FORMAT_R8G8B8A8_UNORM, VK_FORMAT_R32G32B32A32_SFLOAT, VK_FORMAT_R32G32B32A32_SFLOAT,
                                     VK_FORMAT_R32G32B32A32_SFLOAT, VK_FORMAT_R32G32B32A32_UINT};

// A part's images share one storage buffer (binding 7), bound whole: the albedo's words from
// 0 on, the normal map's from this word on (params.dims2.y).
std::size_t normalMapFirstWord(const MesoLook& o) { return o.albedo ? o.albedo->words.size() : 0; }

// What the scene holds for every part: image, frames, camera, light, the plane or the base mesh.
void validateScene(const Context& ctx, const MesoRenderOptions& o) {
    if (o.width < 1 || o.height < 1 || o.width > 4096 || o.height > 4096)
        throw ArgumentError("meso renderer: image size " + std::to_string(o.width) + " x " + std::to_string(o.height) +
                            " out of range [1, 4096]");
    if (o.frames < 1 || o.warmup < 0) throw ArgumentError("meso renderer: frames must be >= 1 and warm-up frames >= 0");
    if (!(o.tileSize > 0) || !(o.planeHalfSize > 0) || o.quads < 1 || o.quads > 256 || !std::isfinite(o.tileSize + o.planeHalfSize))
        throw ArgumentError("meso renderer: tile size, depth and plane size must be finite and > 0, quads in 1..256");
    if (!std::isfinite(o.camera.eye.x + o.camera.eye.y + o.camera.eye.z)) throw ArgumentError("meso renderer: the camera must be finite");
    if (!o.base && !(o.camera.eye.z > 0)) throw ArgumentError("meso renderer: the camera must be above the plane z = 0 (eye.z > 0)");
    if (o.base) {
        const std::size_t n = o.base->corners.size();
        if (n == 0 || n % 3 != 0 || n > kMaxFrameCorners)
            throw ArgumentError("meso renderer: the base mesh has " + std::to_string(n) + " corners (three a triangle, 3 .. " +
                                std::to_string(kMaxFrameCorners) + ")");
        if (n * sizeof(GpuFrameVertex) > ctx.properties().limits.maxStorageBufferRange)
            throw ArgumentError("meso renderer: the base mesh's " + std::to_string(n * sizeof(GpuFrameVertex)) + " bytes exceed the device's maxStorageBufferRange (" +
                                std::to_string(ctx.properties().limits.maxStorageBufferRange) + ")");
        for (std::size_t i = 0; i < n; ++i) {
            const FrameVertex& v = o.base->corners[i];
            const double sum =
                glm::dot(glm::dvec3(1.0), glm::abs(v.position) + glm::abs(v.pS) + glm::abs(v.pT) + glm::abs(v.normal)) + glm::dot(glm::dvec4(1.0), glm::abs(v.shape));
            if (!(sum <= kMaxDrawValue))
                throw ArgumentError("meso renderer: base mesh corner " + std::to_string(i) + " has a value that is not finite or beyond +-" +
                                    dispmap::detail::drawNumber(kMaxDrawValue) + " (the GPU holds it as a float)");
            if (o.base->shaped && !(v.shape.w <= 0))
                throw ArgumentError("meso renderer: base mesh corner " + std::to_string(i) +
                                    ": its most convex principal curvature (FrameVertex::shape.w) is positive");
            if (!(frameIndependence(v.pS, v.pT, v.normal) >= kMinFrameIndependence) || !(std::abs(glm::length(v.normal) - 1.0) < 1e-3))
                throw ArgumentError("meso renderer: base mesh corner " + std::to_string(i) + ": its frame is singular or its normal not of unit length");
        }
    }
    if ((o.silhouettes || o.bentRays) && !(o.base && o.base->shaped)) {
        const std::string what = o.bentRays ? "bent rays" : "silhouettes";
        throw ArgumentError(o.base ? "meso renderer: " + what + " need the base mesh's curvature (FrameMeshOptions::shape)"
                                   : "meso renderer: " + what + " need a curved base mesh (the plane has none)");
    }
    if (!(o.camera.fovYDeg > 0 && o.camera.fovYDeg < 180)) throw ArgumentError("meso renderer: field of view must be in (0, 180) degrees");
    if (!(glm::length(o.lightDirection) > 0) || !std::isfinite(glm::length(o.lightDirection)))
        throw ArgumentError("meso renderer: the light direction must be finite and non-zero");
}

// One part: its technique and look against its maps, and its corners' texture coordinates
// (corners [first, first + count) of the base).
void validateLook(const Context& ctx, const MesoMaps& maps, const MesoLook& o, const MesoRenderOptions& scene, std::size_t first,
                  std::size_t count) {
    const MesoTechnique& t = o.technique;
    if ((t.method == MesoMethod::DistanceMap || t.method == MesoMethod::Ddm) && t.iterations < 1)
        throw ArgumentError("meso renderer: the technique needs at least one iteration (" + std::to_string(t.iterations) + ")");
    if ((t.method == MesoMethod::Relief || t.method == MesoMethod::Pom) && (t.linear < 1 || t.linear > kMaxMesoLinearSteps))
        throw ArgumentError("meso renderer: relief mapping / POM need 1 to " + std::to_string(kMaxMesoLinearSteps) + " linear steps");
    if (t.method == MesoMethod::Relief && t.binary < 0) throw ArgumentError("meso renderer: relief mapping needs binary >= 0");
    if (t.method == MesoMethod::Ddm && (t.exitRule < 0 || t.exitRule > 1)) throw ArgumentError("meso renderer: exit rule must be 0 or 1");
    if (!std::isfinite(t.eps)) throw ArgumentError("meso renderer: eps must be finite");
    if (maps.isSolid() && t.method != MesoMethod::Ddm)
        throw ArgumentError("meso renderer: a solid (non-height-field) mesostructure is marched by the DDM (technique 'ddm'); the others read heights");
    if (maps.isSolid() && o.normalMap)
        throw ArgumentError("meso renderer: a solid (non-height-field) mesostructure is shaded by its own normals; a normal map needs a height field");
    if (scene.bentRays && t.method == MesoMethod::Ddm && !maps.ddm.grid.empty() && !maps.ddm.cones.isotropic && !maps.ddm.cones.shadow)
        throw ArgumentError("meso renderer: bent rays rise again where the base is convex: their DDM needs shadow cones (ConeSet::shadow) or to be isotropic");
    if (!(o.depth > 0) || !std::isfinite(o.depth)) throw ArgumentError("meso renderer: the slab depth must be finite and > 0");
    // The maps the technique reads (buildMesoMaps leaves out what its options do not ask for).
    const bool ddm = t.method == MesoMethod::Ddm || o.shadows,
               quadrics = !maps.isSolid() && ((t.method == MesoMethod::Ddm && t.quadrics) || o.shadows);
    if ((ddm && maps.ddm.grid.empty()) || (t.method == MesoMethod::DistanceMap && maps.distance.d.empty()) ||
        (quadrics && maps.quadrics.q.empty()))
        throw ArgumentError(std::string("meso renderer: the maps lack the ") +
                            (ddm && maps.ddm.grid.empty() ? "DDM" : quadrics && maps.quadrics.q.empty() ? "quadrics" : "distance map") +
                            " the technique" + (o.shadows ? " or its shadows read" : " reads") + " (mesoMapOptionsFor builds what a technique needs)");
    if (!(o.checkerVoxels >= 0 && o.checkerVoxels <= 1e6)) throw ArgumentError("meso renderer: the checker period must be in [0, 1e6] voxels");
    if (scene.base)
        for (std::size_t i = first; i < first + count; ++i) {
            const FrameVertex& v = scene.base->corners[i];
            if (!(std::max(std::abs(v.tex.x) * maps.field.width, std::abs(v.tex.y) * maps.field.height) <= kMaxFrameVoxel))
                throw ArgumentError("meso renderer: base mesh corner " + std::to_string(i) + ": texture coordinate beyond " +
                                    dispmap::detail::drawNumber(kMaxFrameVoxel) + " voxels (buildFrameMesh keeps them near the origin)");
        }
    const auto checkImage = [](const std::shared_ptr<const MesoAlbedo>& image, const char* what) {
        if (!image) return;
        if (const std::string why = mesoAlbedoProblem(*image); !why.empty())
            throw ArgumentError(std::string("meso renderer: the ") + what + "'s words do not hold its levels (build it with mesoAlbedo): " + why);
    };
    checkImage(o.albedo, "albedo");
    checkImage(o.normalMap, "normal map");
    const std::uint64_t imageBytes = 4 * (std::uint64_t{normalMapFirstWord(o)} + (o.normalMap ? o.normalMap->words.size() : 0));
    if (imageBytes > ctx.properties().limits.maxStorageBufferRange)
        throw ArgumentError("meso renderer: the albedo and normal map take " + std::to_string(imageBytes) +
                            " bytes, beyond the device's maxStorageBufferRange (" + std::to_string(ctx.properties().limits.maxStorageBufferRange) +
                            "): smaller images, or no mips");
    if (maps.isSolid()) {
        // The solid's buffers (packSolid): a word a voxel and an entry, 48 bytes a triangle.
        const std::uint64_t lists = 4 * std::uint64_t{maps.solid.entryStart.size() + maps.solid.entries.size()},
                            triangles = 48 * std::uint64_t{maps.solid.triangles.size()};
        if (std::max(lists, triangles) > ctx.properties().limits.maxStorageBufferRange)
            throw ArgumentError("meso renderer: the solid's " + std::string(lists > triangles ? "lists take " : "triangles take ") +
                                std::to_string(std::max(lists, triangles)) + " bytes, beyond the device's maxStorageBufferRange (" +
                                std::to_string(ctx.properties().limits.maxStorageBufferRange) + "): fewer voxels or triangles");
        if (maps.solid.normals.size() != maps.solid.vertices.size())
            throw ArgumentError("meso renderer: the solid has no corner normals (build it with mesoSolidFromMesh)");
    }
    if (o.normalMap && !(std::isfinite(o.normalScale) && std::abs(o.normalScale) <= kMaxNormalScale))
        throw ArgumentError("meso renderer: the normal map's scale must be finite and within +-" + dispmap::detail::drawNumber(kMaxNormalScale));
    if (o.shadows) {
        if (!maps.ddm.cones.shadow && !maps.ddm.cones.isotropic)
            throw ArgumentError("meso renderer: shadows need a DDM with shadow cones (build the maps with ConeSet::shadow = true), "
                                "these have " + maps.ddm.cones.name());
        if (!scene.base && !(scene.lightDirection.z > 0)) throw ArgumentError("meso renderer: shadows need a light above the horizon (z > 0)");
        if (o.shadowIterations < 1) throw ArgumentError("meso renderer: shadow iterations must be >= 1");
    }
    (void)mesoGpuSize(maps); // sizes agree
}

// The parts against the scene: a base for several, counts summing to its triangles.
void validateParts(std::span<const MesoPart> parts, const MesoRenderOptions& scene) {
    if (parts.empty() || parts.size() > 255)
        throw ArgumentError("meso renderer: " + std::to_string(parts.size()) + " mesostructures (1 .. 255)");
    if (parts.size() > 1 && !scene.base) throw ArgumentError("meso renderer: several mesostructures need a base mesh (the plane is one part)");
    std::int64_t sum = 0;
    for (std::size_t i = 0; i < parts.size(); ++i) {
        if (!parts[i].maps) throw ArgumentError("meso renderer: mesostructure " + std::to_string(i) + " has no maps");
        if (parts[i].triangles < 0) throw ArgumentError("meso renderer: mesostructure " + std::to_string(i) + " covers a negative number of triangles");
        sum += parts[i].triangles;
    }
    const std::int64_t triangles = scene.base ? static_cast<std::int64_t>(scene.base->corners.size() / 3)
                                              : std::int64_t{2} * scene.quads * scene.quads;
    if (sum != triangles)
        throw ArgumentError("meso renderer: the mesostructures cover " + std::to_string(sum) + " triangles, the base has " + std::to_string(triangles));
    // A base grouped by groupFrameMesh: a part a group, in its order.
    if (scene.base && !scene.base->groups.empty()) {
        const std::vector<int>& g = scene.base->groups;
        bool same = g.size() == parts.size();
        for (std::size_t i = 0; same && i < g.size(); ++i) same = g[i] == parts[i].triangles;
        if (!same)
            throw ArgumentError("meso renderer: the base mesh has " + std::to_string(g.size()) +
                                " groups of triangles (FrameMesh::groups); give a mesostructure each, with its group's triangle count, in order");
    }
}

} // namespace

glm::dvec3 mesoVoxelsPerUnit(const MesoMaps& maps, const MesoLook& look, const MesoRenderOptions& scene) {
    const double tile = scene.base ? 1.0 : scene.tileSize;
    return {double(maps.field.width) / tile, double(maps.field.height) / tile, double(maps.field.layers) / look.depth};
}

glm::dvec3 mesoVoxelsPerUnit(const MesoMaps& maps, const MesoRenderOptions& o) { return mesoVoxelsPerUnit(maps, o, o); }

glm::dmat4 mesoViewProjection(const MesoRenderOptions& o) {
    double far = 4.0 * (glm::length(o.camera.eye - o.camera.target) + 2.0 * o.planeHalfSize);
    if (o.base) { // beyond the farthest corner, with room for the slab below it
        far = 0.0;
        for (const FrameVertex& v : o.base->corners) far = std::max(far, glm::length(v.position - o.camera.eye));
        far = 2.0 * far + 2.0 * o.depth;
    }
    glm::dmat4 proj = glm::perspectiveRH_ZO(glm::radians(o.camera.fovYDeg), double(o.width) / double(o.height), 1e-3, far);
    proj[1][1] = -proj[1][1]; // Vulkan's y points down
    return proj * glm::lookAtRH(o.camera.eye, o.camera.target, o.camera.up);
}

// One mesostructure on the GPU: its maps, parameters, images, descriptor set and pipeline,
// and the range of vertices it draws.
struct MesoPartGpu {
    MesoLook look;
    MesoBuffers maps;
    bool solid = false; // non-height-field detail (MesoMaps::isSolid)
    std::unique_ptr<Buffer> params;
    std::unique_ptr<Buffer> images; // the albedo's and the normal map's MesoAlbedo::words, or a placeholder
    std::unique_ptr<DescriptorSet> descriptors;
    std::unique_ptr<GraphicsPipeline> pipeline;
    std::uint32_t firstVertex = 0, vertices = 0;
};

struct MesoRenderer::Impl {
    Context& ctx;
    MesoRenderOptions options; // the scene; its depth the deepest part's (the far plane's room)
    std::vector<MesoPartGpu> parts;
    std::unique_ptr<Buffer> frame; // the base mesh's corners, or a placeholder
    std::unique_ptr<OffscreenTargets> targets;
    std::unique_ptr<Timestamps> timestamps;

    Impl(Context& c, const MesoRenderOptions& o) : ctx(c), options(o) {}
    ~Impl() {
        ctx.fn().vkDeviceWaitIdle(ctx.device());
        timestamps.reset();
        for (MesoPartGpu& p : parts) {
            p.pipeline.reset();
            p.descriptors.reset();
        }
        targets.reset();
    }

    void writeFrame() {
        std::vector<GpuFrameVertex> corners(options.base ? options.base->corners.size() : 1);
        if (options.base)
            for (std::size_t i = 0; i < corners.size(); ++i) {
                const FrameVertex& v = options.base->corners[i];
                corners[i] = {glm::vec4(glm::vec3(v.position), float(v.tex.x)), glm::vec4(glm::vec3(v.pS), float(v.tex.y)),
                              glm::vec4(glm::vec3(v.pT), 0.0f), glm::vec4(glm::vec3(v.normal), 0.0f), glm::vec4(v.shape)};
            }
        frame = std::make_unique<Buffer>(ctx, corners.size() * sizeof(GpuFrameVertex));
        frame->upload(corners.data(), corners.size() * sizeof(GpuFrameVertex));
    }

    void addPart(const MesoMaps& m, const MesoLook& look, std::uint32_t firstVertex, std::uint32_t vertices) {
        MesoPartGpu& g =
            parts.emplace_back(MesoPartGpu{look, uploadMesoMaps(ctx, m), m.isSolid(), nullptr, nullptr, nullptr, nullptr, firstVertex, vertices});
        const MesoGpuSize s = mesoGpuSize(m);
        const glm::dvec3 vpu = mesoVoxelsPerUnit(m, look, options);
        GpuMesoParams p{};
        p.viewProj = glm::mat4(mesoViewProjection(options));
        p.eye = glm::vec4(glm::vec3(options.camera.eye), 1.0f);
        p.light = glm::vec4(glm::vec3(glm::normalize(options.lightDirection)), float(options.ambient));
        p.voxelsPerUnit = glm::vec4(glm::vec3(vpu), float(look.checkerVoxels));
        p.plane = glm::vec4(float(options.planeHalfSize), float(options.quads), 0.0f, 0.0f);
        p.background = glm::vec4(glm::vec3(options.background), 1.0f);
        p.dims0 = glm::ivec4(s.width, s.height, s.layers, s.block);
        p.dims1 = glm::ivec4(s.gx, s.gy, s.gz, s.coneM);
        p.dims2 = glm::ivec4(s.coneN, static_cast<int>(normalMapFirstWord(look)), static_cast<int>(parts.size() - 1), 0);
        p.tol = glm::vec4(s.tol, float(look.shadowOffset), float(look.normalScale), look.normalGreenUp ? -1.0f : 1.0f);
        g.params = std::make_unique<Buffer>(ctx, sizeof p);
        g.params->upload(&p, sizeof p);
        // The images one after the other (normalMapFirstWord); none: a placeholder.
        std::vector<std::uint32_t> words;
        if (look.albedo) words = look.albedo->words;
        if (look.normalMap) words.insert(words.end(), look.normalMap->words.begin(), look.normalMap->words.end());
        if (words.empty()) words.assign(4, 0u);
        g.images = std::make_unique<Buffer>(ctx, words.size() * sizeof(std::uint32_t));
        g.images->upload(words.data(), words.size() * sizeof(std::uint32_t));
    }

    void create() {
        const VkFormat depth = options.base ? VK_FORMAT_D32_SFLOAT : VK_FORMAT_UNDEFINED;
        if (options.base) requireFormat(ctx, depth, VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT, "the mesostructure renderer's depth");
        targets = std::make_unique<OffscreenTargets>(ctx, options.width, options.height, kFormats, depth);
        for (MesoPartGpu& g : parts) {
            const auto mb = g.maps.all(); // maps 0..4, params 5, base mesh 6, images 7, a solid's lists 8 and 9
            std::array<VkBuffer, 10> storage{};
            for (std::size_t i = 0; i < 5; ++i) storage[i] = mb[i]->handle();
            storage[5] = g.params->handle();
            storage[6] = frame->handle();
            storage[7] = g.images->handle();
            storage[8] = mb[5]->handle();
            storage[9] = mb[6]->handle();
            g.descriptors = std::make_unique<DescriptorSet>(ctx, storage, std::span<const SampledImage>{},
                                                            VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT);
            const MesoTechnique& t = g.look.technique;
            const float eps = static_cast<float>(t.eps);
            std::uint32_t epsBits;
            std::memcpy(&epsBits, &eps, sizeof epsBits);
            GraphicsPipelineDesc d;
            d.specConstants = {static_cast<std::uint32_t>(t.method),
                               static_cast<std::uint32_t>(t.iterations),
                               epsBits,
                               t.quadrics ? 1u : 0u,
                               static_cast<std::uint32_t>(t.exitRule),
                               static_cast<std::uint32_t>(t.linear),
                               static_cast<std::uint32_t>(t.binary),
                               g.look.shadows ? 1u : 0u,
                               static_cast<std::uint32_t>(g.look.shadowIterations),
                               options.base ? 1u : 0u,
                               g.look.albedo ? 1u : 0u,
                               g.look.normalMap ? 1u : 0u,
                               g.solid ? 1u : 0u,
                               options.silhouettes ? 1u : 0u,
                               options.bentRays ? 1u : 0u};
            d.stages = {{VK_SHADER_STAGE_VERTEX_BIT, options.base ? std::span<const std::uint32_t>(meso_base_vert_spv)
                                                                  : std::span<const std::uint32_t>(meso_vert_spv), false},
                        {VK_SHADER_STAGE_FRAGMENT_BIT, meso_frag_spv, true}};
            // A miss writes the far plane (1): LESS_OR_EQUAL lets it cover the clear, never a hit.
            d.depthFormat = depth;
            d.depthCompare = VK_COMPARE_OP_LESS_OR_EQUAL;
            d.colorFormats.assign(std::begin(kFormats), std::end(kFormats));
            d.layout = g.descriptors->pipelineLayout();
            g.pipeline = std::make_unique<GraphicsPipeline>(ctx, d);
        }
        timestamps = std::make_unique<Timestamps>(ctx);
    }

    void record(VkCommandBuffer cmd, bool readBackNow) {
        const Functions& fn = ctx.fn();
        const auto w = static_cast<std::uint32_t>(options.width), h = static_cast<std::uint32_t>(options.height);
        timestamps->begin(cmd);
        std::array<VkClearColorValue, kTargets> clear{};
        const glm::vec3 bg(options.background);
        clear[0] = {{bg.x, bg.y, bg.z, 1.0f}};
        clear[1] = {{0.0f, 0.0f, 0.0f, -1.0f}};
        clear[2] = {{0.0f, 0.0f, 0.0f, 1.0f}}; // w 1: not covered (meso.frag writes the curve there, <= 0)
        clear[3] = {{0.0f, 0.0f, 0.0f, 0.0f}};
        clear[4].uint32[0] = clear[4].uint32[1] = clear[4].uint32[2] = clear[4].uint32[3] = 0;
        targets->beginRendering(cmd, clear);
        const VkViewport viewport{0.0f, 0.0f, float(w), float(h), 0.0f, 1.0f};
        const VkRect2D scissor{{0, 0}, {w, h}};
        fn.vkCmdSetViewport(cmd, 0, 1, &viewport);
        fn.vkCmdSetScissor(cmd, 0, 1, &scissor);
        // One pipeline a mesostructure over its triangles, all into the one depth buffer.
        for (const MesoPartGpu& g : parts) {
            if (g.vertices == 0) continue;
            g.descriptors->bind(cmd);
            fn.vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, g.pipeline->handle());
            fn.vkCmdDraw(cmd, g.vertices, 1, g.firstVertex, 0);
        }
        targets->endRendering(cmd);
        timestamps->end(cmd);
        if (readBackNow) targets->copyToReadBack(cmd);
        memoryBarrier(fn, cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
                      VK_ACCESS_HOST_READ_BIT);
    }
};

namespace {
void requireDynamicRendering(const Context& context) {
    if (!context.dynamicRenderingEnabled())
        throw VulkanError("Vulkan device '" + context.deviceName() +
                          "': dynamic rendering is not enabled (Vulkan 1.3 dynamicRendering or VK_KHR_dynamic_rendering), "
                          "which the mesostructure renderer draws with");
}
} // namespace

MesoRenderer::MesoRenderer(Context& context, const MesoMaps& maps, const MesoRenderOptions& options) {
    validateScene(context, options);
    const std::size_t vertices = options.base ? options.base->corners.size() : static_cast<std::size_t>(6 * options.quads * options.quads);
    validateLook(context, maps, options, options, 0, options.base ? vertices : 0);
    requireDynamicRendering(context);
    impl_ = std::make_unique<Impl>(context, options);
    impl_->writeFrame();
    impl_->addPart(maps, options, 0, static_cast<std::uint32_t>(vertices));
    impl_->create();
}

MesoRenderer::MesoRenderer(Context& context, std::span<const MesoPart> parts, const MesoRenderOptions& scene) {
    validateScene(context, scene);
    validateParts(parts, scene);
    std::size_t first = 0;
    MesoRenderOptions o = scene;
    std::vector<std::uint32_t> firstVertex(parts.size());
    for (std::size_t i = 0; i < parts.size(); ++i) {
        const MesoPart& p = parts[i];
        firstVertex[i] = static_cast<std::uint32_t>(first);
        try {
            validateLook(context, *p.maps, p.look, scene, scene.base ? first : 0, scene.base ? 3 * static_cast<std::size_t>(p.triangles) : 0);
        } catch (const ArgumentError& e) { // the same message, naming the part
            const std::string what = e.what(), prefix = "meso renderer: ";
            throw ArgumentError(prefix + "mesostructure " + std::to_string(i) + ": " +
                                (what.rfind(prefix, 0) == 0 ? what.substr(prefix.size()) : what));
        }
        first += 3 * static_cast<std::size_t>(p.triangles);
        o.depth = i == 0 ? p.look.depth : std::max(o.depth, p.look.depth);
    }
    requireDynamicRendering(context);
    impl_ = std::make_unique<Impl>(context, o);
    impl_->writeFrame();
    for (std::size_t i = 0; i < parts.size(); ++i)
        impl_->addPart(*parts[i].maps, parts[i].look, firstVertex[i], static_cast<std::uint32_t>(3 * static_cast<std::size_t>(parts[i].triangles)));
    impl_->create();
}

MesoRenderer::~MesoRenderer() = default;

MesoImage MesoRenderer::render() {
    Impl& m = *impl_;
    std::vector<double> times;
    const int total = m.options.warmup + m.options.frames;
    for (int i = 0; i < total; ++i) {
        m.ctx.submitAndWait([&](VkCommandBuffer cmd) { m.record(cmd, i + 1 == total); });
        if (i >= m.options.warmup && m.ctx.timestampsSupported()) times.push_back(m.timestamps->milliseconds());
    }
    MesoImage out;
    out.width = m.options.width;
    out.height = m.options.height;
    out.gpuMs = median(times);
    out.frames = m.options.frames;
    const std::size_t pixels = static_cast<std::size_t>(out.width) * static_cast<std::size_t>(out.height);
    out.rgba.resize(pixels * 4);
    m.targets->readBack(0).download(out.rgba.data(), out.rgba.size());
    std::vector<glm::vec4> origin(pixels), dir(pixels);
    std::vector<glm::uvec4> counts(pixels);
    out.hitPoint.resize(pixels);
    m.targets->readBack(1).download(out.hitPoint.data(), pixels * sizeof(glm::vec4));
    m.targets->readBack(2).download(origin.data(), pixels * sizeof(glm::vec4));
    m.targets->readBack(3).download(dir.data(), pixels * sizeof(glm::vec4));
    m.targets->readBack(4).download(counts.data(), pixels * sizeof(glm::uvec4));
    out.iterations.resize(pixels);
    out.shadowIterations.resize(pixels);
    out.covered.resize(pixels);
    out.hit.resize(pixels);
    out.cut.resize(pixels);
    out.shadowed.resize(pixels);
    out.rayOrigin.resize(pixels);
    out.rayDir.resize(pixels);
    out.part.resize(pixels);
    out.bend.resize(pixels);
    out.curve.resize(pixels);
    for (std::size_t i = 0; i < pixels; ++i) {
        out.covered[i] = origin[i].w <= 0.5f ? 1 : 0;
        out.iterations[i] = counts[i].x;
        out.shadowIterations[i] = counts[i].y;
        out.shadowed[i] = (counts[i].z & 1u) ? 1 : 0;
        out.hit[i] = counts[i].w == 1u ? 1 : 0;
        out.cut[i] = counts[i].w == 2u ? 1 : 0;
        out.rayOrigin[i] = glm::vec3(origin[i]);
        out.rayDir[i] = glm::vec3(dir[i]);
        out.part[i] = static_cast<std::uint8_t>(std::min(counts[i].z >> 1, 255u));
        out.bend[i] = dir[i].w;
        out.curve[i] = out.covered[i] ? origin[i].w : 0.0f;
    }
    return out;
}

MesoImage renderMeso(Context& context, const MesoMaps& maps, const MesoRenderOptions& options) {
    MesoRenderer r(context, maps, options);
    return r.render();
}

MesoImage renderMeso(Context& context, std::span<const MesoPart> parts, const MesoRenderOptions& scene) {
    MesoRenderer r(context, parts, scene);
    return r.render();
}

} // namespace dispmap::vulkan
