// SurfaceRenderer: upload of the packed surface and topology, the tessellation pipelines of the
// draw's effects (dynamic rendering, the caller's or the offscreen formats), the per-frame
// update (vkCmdUpdateBuffer) and draw recorded into any command buffer, and render(): frames
// into offscreen targets with timestamps, statistics and the read-back (gpu_objects.h).
#include "dispmap/vulkan/renderer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>

#include "dispmap/surface/packed_surface.h"
#include "dispmap/surface/tessellator.h"
#include "dispmap/vulkan/buffer.h"
#include "gpu_objects.h"

// SPIR-V of shaders/render/*, built by backend_vulkan/CMakeLists.txt.
#include "render_frag_spv.h"
#include "render_frag_lean_spv.h"
#include "render_frag_color_spv.h"
#include "render_frag_color_lean_spv.h"
#include "render_tesc_spv.h"
#include "render_tesc_lean_spv.h"
#include "render_tese_fe_spv.h"
#include "render_tese_fe_lean_spv.h"
#include "render_tese_int_spv.h"
#include "render_tese_int_lean_spv.h"
#include "render_vert_spv.h"

namespace dispmap::vulkan {

using namespace detail;

namespace {

// --- The layouts of shaders/render/common.glsl (std430).
struct GpuLight {
    glm::vec4 direction, color;
};
struct GpuParams {
    glm::mat4 viewProj;
    glm::vec4 eye, viewport, tess, albedo, wireColor, atlas;
    glm::ivec4 counts;
    GpuLight lights[kMaxLights];
};
static_assert(sizeof(GpuParams) == 64 + 6 * 16 + 16 + kMaxLights * 32, "Params block of common.glsl");
struct GpuFace {
    glm::uvec4 corners;
    glm::ivec4 info;
    glm::uvec4 chart;
};
static_assert(sizeof(GpuFace) == 48, "Face of common.glsl");
struct GpuBaseVertex {
    glm::vec4 position;
    glm::ivec4 ring;
};
static_assert(sizeof(GpuBaseVertex) == 32, "BaseVertex of common.glsl");
struct GpuCaptured {
    glm::vec4 position, faceUV;
};
constexpr std::uint32_t kCaptureHeader = 16;

enum Binding : std::uint32_t {
    kParams, kPoints, kPatchIndices, kPatches, kNodes, kFaceRoots, kCornerNormals, kTexels, kRecords,
    kFaces, kBaseVertices, kRingIndices, kTileVertices, kSpreadIndices, kDrawFaces, kCapture,
    kStorageBindings, // = 16
    kBaselineHeight = kStorageBindings, kBaselineNormal, kPackedImage, kBindingCount
};

template <class T> std::size_t bytesOf(const std::vector<T>& v) { return v.size() * sizeof(T); }

/// The per-face, per-vertex topology the control shader reads (see surface.tesc).
struct Topology {
    std::vector<GpuFace> faces;
    std::vector<GpuBaseVertex> baseVertices;
    std::vector<std::uint32_t> ring, spread, drawFaces;
    std::vector<glm::uvec2> tileVertices;
};

Topology buildTopology(const DisplacedSurface& surface, const BaselineAtlas* atlas) {
    const BaseSurface& base = surface.base();
    const TileTopology& topo = base.topology();
    const Far::TopologyLevel& L = base.refiner().GetLevel(0);
    const int nv = L.GetNumVertices(), ne = L.GetNumEdges();
    Topology t;

    // Base vertices: limit position, mip floor (Tessellator: base resolution 2 at vertices of
    // non-quad faces), kMin for the texel-ratio rule, and the one-ring for the screen-space methods.
    const std::vector<glm::dvec3> limit = baseVertexLimitPositions(base);
    const VertexMipLimits mips = vertexMipLimits(surface);
    t.baseVertices.resize(static_cast<std::size_t>(nv));
    for (int v = 0; v < nv; ++v) {
        const Far::ConstIndexArray edges = L.GetVertexEdges(v);
        const int offset = static_cast<int>(t.ring.size());
        for (int i = 0; i < edges.size(); ++i) {
            const Far::ConstIndexArray ev = L.GetEdgeVertices(edges[i]);
            t.ring.push_back(static_cast<std::uint32_t>(ev[0] == v ? ev[1] : ev[0]));
        }
        GpuBaseVertex& g = t.baseVertices[static_cast<std::size_t>(v)];
        g.position = glm::vec4(glm::vec3(limit[static_cast<std::size_t>(v)]), float(mips.floorRes[static_cast<std::size_t>(v)]));
        g.ring = glm::ivec4(offset, edges.size(), mips.kMin[static_cast<std::size_t>(v)], L.IsVertexBoundary(v) ? 0 : 1);
    }
    // TileTopology vertices: the base vertices they are the mean of.
    t.tileVertices.resize(static_cast<std::size_t>(topo.vertexCount()));
    for (int id = 0; id < topo.vertexCount(); ++id) {
        const auto offset = static_cast<std::uint32_t>(t.spread.size());
        if (id < nv) {
            t.spread.push_back(static_cast<std::uint32_t>(id));
        } else if (id < nv + ne) {
            const Far::ConstIndexArray ev = L.GetEdgeVertices(id - nv);
            t.spread.push_back(static_cast<std::uint32_t>(ev[0]));
            t.spread.push_back(static_cast<std::uint32_t>(ev[1]));
        } else {
            const Far::ConstIndexArray fv = L.GetFaceVertices(id - nv - ne);
            for (int i = 0; i < fv.size(); ++i) t.spread.push_back(static_cast<std::uint32_t>(fv[i]));
        }
        t.tileVertices[static_cast<std::size_t>(id)] = glm::uvec2(offset, static_cast<std::uint32_t>(t.spread.size()) - offset);
    }
    // Faces: corners, sub-face flag, auto flag, T-junction edges, baseline chart.
    auto anyFace = [&](int edge, bool quad) {
        const Far::ConstIndexArray ef = L.GetEdgeFaces(edge);
        if (ef.size() < 2) return false; // a boundary edge has no neighbour to match
        for (int i = 0; i < ef.size(); ++i)
            if ((L.GetFaceVertices(ef[i]).size() == 4) == quad) return true;
        return false;
    };
    t.faces.resize(static_cast<std::size_t>(topo.tileCount()));
    for (int f = 0; f < topo.tileCount(); ++f) {
        GpuFace& g = t.faces[static_cast<std::size_t>(f)];
        int tBits = 0;
        for (int e = 0; e < 4; ++e) {
            const int x = topo.cornerVertex(f, e), y = topo.cornerVertex(f, e + 1);
            g.corners[e] = static_cast<std::uint32_t>(x);
            if (x < nv && y < nv) { // a whole base edge of a quad: T-junction if an N-gon is across
                const int edge = L.FindEdge(x, y);
                if (edge >= 0 && anyFace(edge, false)) tBits |= 1 << e;
            } else if ((x < nv) != (y < nv) && std::max(x, y) < nv + ne) { // half of an N-gon's edge
                if (anyFace(std::max(x, y) - nv, true)) tBits |= 1 << e;
            }
        }
        const bool autoAccurate = surface.autoFaces()[static_cast<std::size_t>(f)] != 0;
        const int sharp = surface.sharpBand() > 0.0 ? base.sharpMask(f) : 0;
        g.info = glm::ivec4(topo.scale(f), autoAccurate ? 1 : 0, tBits, sharp);
        g.chart = atlas && atlas->layout == BaselineLayout::Faces ? glm::uvec4(atlas->chartOrigins[static_cast<std::size_t>(f)], 0, 0)
                                                                  : glm::uvec4(0);
        if (!base.isHole(f)) t.drawFaces.push_back(static_cast<std::uint32_t>(f));
    }
    return t;
}

int techniqueIndex(Technique t) { return t == Technique::Base ? 0 : t == Technique::Displaced ? 1 : 2; }
int normalsIndex(NormalMode m) { return m == NormalMode::Approximate ? 0 : m == NormalMode::Accurate ? 1 : 2; }
int lodIndex(MipSelection m) { return m == MipSelection::Off ? 0 : m == MipSelection::TessFactor ? 1 : 2; }
int methodIndex(TessMethod m) {
    switch (m) {
    case TessMethod::Uniform: return 0;
    case TessMethod::Distance: return 1;
    case TessMethod::ScreenEdge: return 2;
    case TessMethod::ScreenArea: return 3;
    }
    return 0;
}

// Offscreen targets of render() (the formats of its RenderedImage).
const VkFormat kColorFormat = VK_FORMAT_R8G8B8A8_UNORM;
const VkFormat kNormalFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
const VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;

constexpr VkPipelineStageFlags kShaderStages =
    VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_TESSELLATION_CONTROL_SHADER_BIT |
    VK_PIPELINE_STAGE_TESSELLATION_EVALUATION_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT;

template <std::size_t N> std::span<const std::uint32_t> spirv(const std::uint32_t (&code)[N]) { return code; }

template <class T> std::vector<std::uint8_t> rawBytes(const std::vector<T>& v) {
    std::vector<std::uint8_t> bytes(bytesOf(v));
    if (!v.empty()) std::memcpy(bytes.data(), v.data(), bytes.size());
    return bytes;
}

} // namespace

glm::dmat4 viewProjection(const Camera& camera, int width, int height) {
    const double aspect = double(width) / double(height);
    glm::dmat4 proj = glm::perspectiveRH_ZO(glm::radians(camera.fovYDeg), aspect, camera.nearPlane, camera.farPlane);
    proj[1][1] = -proj[1][1]; // Vulkan's y points down
    return proj * glm::lookAtRH(camera.eye, camera.target, camera.up);
}

struct SurfaceRenderer::Impl {
    Context& ctx;
    const DisplacedSurface& surface;
    SurfaceDraw draw;
    RendererOptions options;
    TargetFormats formats; // the attachments the pipelines draw into
    int width = 0, height = 0;
    std::uint32_t drawCount = 0;
    std::size_t uploaded = 0;
    int packedWidth = 0, atlasW = 1, atlasH = 1, atlasN = 1;
    bool baselineUv = false; // the baseline atlas is in the mesh's UV layout

    std::vector<Buffer> buffers;             // by binding, kParams .. kCapture
    std::vector<GpuBaseVertex> baseVertices; // what kBaseVertices holds (positions move with the cage)
    struct Pending {
        Binding binding;
        std::vector<std::uint8_t> bytes;
        VkDeviceSize offset = 0;
        /// The image path: the texel rectangle (x, y, width, height) of the packed image to copy
        /// from the texel buffer once it holds these bytes; width 0: none.
        glm::ivec4 imageRect{0};
    };
    std::vector<Pending> pending; // geometry and tiles for the next recordUpdate
    PackedTiles packed;           // what kTexels holds (edited tiles are written into it)
    Image baseHeight, baseNormal;
    Image packedImage; // the packed tiles as an R32F / R16F image (TexelPath::Image), else 1 x 1
    bool imagePath = false;
    VkSampler nearest = VK_NULL_HANDLE; // packedImage is read by texelFetch only
    VkSampler sampler = VK_NULL_HANDLE;
    std::unique_ptr<DescriptorSet> descriptors;
    std::unique_ptr<GraphicsPipeline> fill, wire;
    std::unique_ptr<Timestamps> timestamps;
    VkQueryPool statistics = VK_NULL_HANDLE;
    std::unique_ptr<OffscreenTargets> targets; // render() only, at the current size

    Impl(Context& c, const SurfaceDraw& s, const DisplacedSurface& surf, RendererOptions o)
        : ctx(c), surface(surf), draw(s), options(o), width(s.width), height(s.height) {
        formats = o.target ? *o.target : TargetFormats{kColorFormat, kNormalFormat, kDepthFormat};
    }
    ~Impl() { destroy(); }

    void destroy() noexcept {
        const Functions& fn = ctx.fn();
        const VkDevice d = ctx.device();
        fn.vkDeviceWaitIdle(d); // frames the caller recorded may still run
        targets.reset();
        timestamps.reset();
        if (statistics) fn.vkDestroyQueryPool(d, statistics, nullptr);
        statistics = VK_NULL_HANDLE;
        wire.reset();
        fill.reset();
        descriptors.reset();
        if (sampler) fn.vkDestroySampler(d, sampler, nullptr);
        sampler = VK_NULL_HANDLE;
        if (nearest) fn.vkDestroySampler(d, nearest, nullptr);
        nearest = VK_NULL_HANDLE;
        packedImage = Image();
        baseNormal = Image();
        baseHeight = Image();
        buffers.clear();
    }

    Buffer& buffer(Binding b) { return buffers[static_cast<std::size_t>(b)]; }

    template <class T> void upload(Binding b, const std::vector<T>& data) {
        const std::size_t bytes = std::max<std::size_t>(bytesOf(data), 16); // no empty buffers
        buffers[static_cast<std::size_t>(b)] = Buffer(ctx, bytes);
        if (!data.empty()) buffers[static_cast<std::size_t>(b)].upload(data.data(), bytesOf(data));
        uploaded += bytesOf(data);
    }

    GpuParams params() const {
        GpuParams p{};
        p.viewProj = glm::mat4(vulkan::viewProjection(draw.camera, width, height));
        p.eye = glm::vec4(glm::vec3(draw.camera.eye), 1.0f);
        p.viewport = glm::vec4(float(width), float(height), float(surface.sharpCapRadius()), 0.0f);
        const SurfaceEffects& e = draw.effects;
        const DisplacedSurfaceOptions& so = surface.options();
        p.tess = glm::vec4(float(e.tessValue), float(e.maxFactor), float(surface.sharpBand()), so.endCapNormals ? 1.0f : 0.0f);
        p.albedo = glm::vec4(glm::vec3(draw.albedo), float(draw.ambient));
        p.wireColor = glm::vec4(0.05f, 0.05f, 0.05f, 1.0f);
        p.counts = glm::ivec4(static_cast<int>(std::min<std::size_t>(draw.lights.size(), kMaxLights)),
                              static_cast<int>(options.captureCapacity), surface.tiles().tileCount() ? packedWidth : 0, 0);
        p.atlas = glm::vec4(float(atlasW), float(atlasH), float(atlasN), 0.0f);
        for (std::size_t i = 0; i < draw.lights.size() && i < kMaxLights; ++i) {
            p.lights[i].direction = glm::vec4(glm::vec3(glm::normalize(draw.lights[i].direction)), 0.0f);
            p.lights[i].color = glm::vec4(glm::vec3(draw.lights[i].color), 0.0f);
        }
        return p;
    }

    void uploadSurface(const BaselineAtlas* atlas) {
        buffers.clear();
        for (std::uint32_t i = 0; i < kStorageBindings; ++i) buffers.emplace_back(ctx, 16);
        if (atlas) {
            atlasW = atlas->width;
            atlasH = atlas->height;
            atlasN = atlas->texelsPerFace;
            baselineUv = atlas->layout == BaselineLayout::MeshUv;
            if (atlas->faceCount() != surface.base().faceCount())
                throw ArgumentError("the baseline atlas has " + std::to_string(atlas->faceCount()) + " faces, the surface " +
                                    std::to_string(surface.base().faceCount()));
            if (baselineUv) { // 6 vec4 a face: corner UVs, then corner tangents (Records of common.glsl, as float bits)
                std::vector<glm::vec4> data;
                data.reserve(6 * static_cast<std::size_t>(atlas->faceCount()));
                for (int f = 0; f < atlas->faceCount(); ++f) {
                    for (int i = 0; i < 2; ++i) data.push_back(atlas->faceUvs[2 * static_cast<std::size_t>(f) + static_cast<std::size_t>(i)]);
                    for (int i = 0; i < 4; ++i) data.push_back(atlas->cornerTangents[4 * static_cast<std::size_t>(f) + static_cast<std::size_t>(i)]);
                }
                upload(kRecords, data);
            }
        }
        const PackedSurface ps(surface.base());
        upload(kPoints, ps.points);
        upload(kPatchIndices, ps.patchIndices);
        upload(kPatches, ps.patches);
        upload(kNodes, ps.nodes);
        upload(kFaceRoots, ps.faceRoots);
        upload(kCornerNormals, ps.cornerNormals);
        if (draw.effects.technique == Technique::Displaced) {
            packed = surface.tiles().pack();
            if (draw.effects.texelFormat == TexelFormat::Half) packed.useHalf();
            packedWidth = packed.width;
            std::vector<glm::uvec4> records;
            for (const PatchRecord& r : packed.records) records.push_back(recordWords(r));
            if (packed.format == TexelFormat::Half) {
                std::vector<std::uint16_t> halves = packed.halfTexels();
                if (halves.size() % 2) halves.push_back(0); // whole words
                upload(kTexels, halves);
            } else {
                upload(kTexels, packed.texels);
            }
            upload(kRecords, records);
        }
        Topology topo = buildTopology(surface, atlas);
        drawCount = static_cast<std::uint32_t>(topo.drawFaces.size());
        upload(kFaces, topo.faces);
        upload(kBaseVertices, topo.baseVertices);
        upload(kRingIndices, topo.ring);
        upload(kTileVertices, topo.tileVertices);
        upload(kSpreadIndices, topo.spread);
        upload(kDrawFaces, topo.drawFaces);
        baseVertices = std::move(topo.baseVertices);
        buffers[kCapture] = Buffer(ctx, kCaptureHeader + std::max<std::size_t>(options.captureCapacity, 1) * sizeof(GpuCaptured));
        const GpuParams p = params(); // recordUpdate writes it again every frame
        upload(kParams, std::vector<GpuParams>{p});
    }

    // The baseline's height and normal maps (1 x 1 placeholders for the other techniques:
    // the descriptors must be valid either way).
    void uploadMaps(const BaselineAtlas* atlas) {
        const Functions& fn = ctx.fn();
        requireFormat(ctx, VK_FORMAT_R32_SFLOAT, VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT,
                      "a linearly filtered texture (baseline height map)");
        const int w = atlas ? atlas->width : 1, h = atlas ? atlas->height : 1;
        std::vector<float> heights = atlas ? atlas->heights : std::vector<float>{0.0f};
        std::vector<std::uint8_t> normals = atlas ? atlas->normals : std::vector<std::uint8_t>{128, 128, 255, 255};
        const VkImageUsageFlags usage = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
        const auto uw = static_cast<std::uint32_t>(w), uh = static_cast<std::uint32_t>(h);
        baseHeight = Image(ctx, uw, uh, VK_FORMAT_R32_SFLOAT, usage);
        baseNormal = Image(ctx, uw, uh, VK_FORMAT_R8G8B8A8_UNORM, usage);
        Buffer staging(ctx, bytesOf(heights) + bytesOf(normals));
        staging.upload(heights.data(), bytesOf(heights));
        staging.upload(normals.data(), bytesOf(normals), bytesOf(heights));
        if (atlas) uploaded += bytesOf(heights) + bytesOf(normals);
        ctx.submitAndWait([&](VkCommandBuffer cmd) {
            VkDeviceSize offset = 0;
            for (const Image* image : {&baseHeight, &baseNormal}) {
                imageBarrier(fn, cmd, image->image(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                             VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0,
                             VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
                VkBufferImageCopy region{};
                region.bufferOffset = offset;
                region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
                region.imageExtent = {uw, uh, 1};
                fn.vkCmdCopyBufferToImage(cmd, staging.handle(), image->image(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
                imageBarrier(fn, cmd, image->image(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                             VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_TRANSFER_BIT,
                             VK_ACCESS_TRANSFER_WRITE_BIT,
                             VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT |
                                 VK_PIPELINE_STAGE_TESSELLATION_EVALUATION_SHADER_BIT,
                             VK_ACCESS_SHADER_READ_BIT);
                offset += bytesOf(heights);
            }
        });
        VkSamplerCreateInfo s{};
        s.sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO;
        s.magFilter = VK_FILTER_LINEAR;
        s.minFilter = VK_FILTER_LINEAR;
        s.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
        // Repeat, as engines sample a UV layout (the mesh-UV baseline's UVs may leave [0, 1]^2);
        // the per-face charts are never read outside.
        s.addressModeU = s.addressModeV = s.addressModeW = VK_SAMPLER_ADDRESS_MODE_REPEAT;
        s.maxLod = 0.0f;
        DISPMAP_VK_CHECK(fn, vkCreateSampler, ctx.device(), &s, nullptr, &sampler);
    }

    // The packed tiles as an image for TexelPath::Image (R32F, or R16F for half texels), filled
    // from the texel buffer, which holds the same bytes row by row; a 1 x 1 placeholder
    // otherwise (the descriptor must be valid either way).
    void uploadPackedImage() {
        const Functions& fn = ctx.fn();
        const bool use = draw.effects.technique == Technique::Displaced && draw.effects.texelPath == TexelPath::Image &&
                         packed.width > 0 && packed.height > 0;
        imagePath = use;
        VkSamplerCreateInfo si{};
        si.sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO;
        si.magFilter = si.minFilter = VK_FILTER_NEAREST;
        si.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
        si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
        DISPMAP_VK_CHECK(fn, vkCreateSampler, ctx.device(), &si, nullptr, &nearest);
        const VkFormat format = use && packed.format == TexelFormat::Half ? VK_FORMAT_R16_SFLOAT : VK_FORMAT_R32_SFLOAT;
        if (use) {
            requireFormat(ctx, format, VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT | VK_FORMAT_FEATURE_TRANSFER_DST_BIT,
                          "a sampled image of the packed tiles (effects.texelPath image)");
            const std::uint32_t limit = ctx.properties().limits.maxImageDimension2D;
            if (static_cast<std::uint32_t>(packed.width) > limit || static_cast<std::uint32_t>(packed.height) > limit)
                throw ArgumentError("the packed tiles are " + std::to_string(packed.width) + " x " + std::to_string(packed.height) +
                                    " texels, beyond the device's largest image (" + std::to_string(limit) +
                                    "): use effects.texelPath buffer");
        }
        const auto w = static_cast<std::uint32_t>(use ? packed.width : 1), h = static_cast<std::uint32_t>(use ? packed.height : 1);
        packedImage = Image(ctx, w, h, format, VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT);
        Buffer zero(ctx, 16);
        const float nothing[4] = {0, 0, 0, 0};
        zero.upload(nothing, sizeof nothing);
        ctx.submitAndWait([&](VkCommandBuffer cmd) {
            imageBarrier(fn, cmd, packedImage.image(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                         VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_ACCESS_TRANSFER_WRITE_BIT);
            VkBufferImageCopy region{};
            region.bufferRowLength = use ? w : 0;
            region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
            region.imageExtent = {w, h, 1};
            fn.vkCmdCopyBufferToImage(cmd, use ? buffer(kTexels).handle() : zero.handle(), packedImage.image(),
                                      VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
            imageBarrier(fn, cmd, packedImage.image(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                         VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                         VK_PIPELINE_STAGE_TESSELLATION_EVALUATION_SHADER_BIT, VK_ACCESS_SHADER_READ_BIT);
        });
        if (use) uploaded += static_cast<std::size_t>(w) * h * (format == VK_FORMAT_R16_SFLOAT ? 2 : 4);
    }

    void createDescriptors() {
        std::array<VkBuffer, kStorageBindings> storage{};
        for (std::uint32_t i = 0; i < kStorageBindings; ++i) storage[i] = buffers[i].handle();
        const SampledImage maps[3] = {{sampler, baseHeight.view()}, {sampler, baseNormal.view()}, {nearest, packedImage.view()}};
        descriptors = std::make_unique<DescriptorSet>(ctx, storage, maps, VK_SHADER_STAGE_ALL_GRAPHICS);
    }

    std::unique_ptr<GraphicsPipeline> createPipeline(bool wireframe) {
        const SurfaceEffects& e = draw.effects;
        const bool displaced = e.technique == Technique::Displaced;
        const bool integer = e.spacing == Spacing::Integer;
        const bool lean = options.lean;
        const bool normalTarget = formats.normal != VK_FORMAT_UNDEFINED;
        GraphicsPipelineDesc d;
        d.specConstants = {static_cast<std::uint32_t>(techniqueIndex(e.technique)),
                           static_cast<std::uint32_t>(displaced ? normalsIndex(e.normals) : 0),
                           static_cast<std::uint32_t>(displaced ? lodIndex(e.lod) : 0),
                           static_cast<std::uint32_t>(methodIndex(e.tessMethod)),
                           options.captureCapacity > 0 ? 1u : 0u,
                           wireframe ? 1u : 0u,
                           displaced && e.texelFormat == TexelFormat::Half ? 1u : 0u,
                           displaced && e.texelPath == TexelPath::Image ? 1u : 0u,
                           e.technique == Technique::Baseline && baselineUv ? 1u : 0u};
        const std::span<const std::uint32_t> frag =
            normalTarget ? (lean ? spirv(render_frag_lean_spv) : spirv(render_frag_spv))
                         : (lean ? spirv(render_frag_color_lean_spv) : spirv(render_frag_color_spv));
        d.stages = {{VK_SHADER_STAGE_VERTEX_BIT, spirv(render_vert_spv)},
                    {VK_SHADER_STAGE_TESSELLATION_CONTROL_BIT, lean ? spirv(render_tesc_lean_spv) : spirv(render_tesc_spv)},
                    {VK_SHADER_STAGE_TESSELLATION_EVALUATION_BIT,
                     integer ? (lean ? spirv(render_tese_int_lean_spv) : spirv(render_tese_int_spv))
                             : (lean ? spirv(render_tese_fe_lean_spv) : spirv(render_tese_fe_spv))},
                    {VK_SHADER_STAGE_FRAGMENT_BIT, frag}};
        d.patchControlPoints = 1;
        d.polygonMode = wireframe ? VK_POLYGON_MODE_LINE : VK_POLYGON_MODE_FILL;
        d.depthBias = wireframe;
        d.depthBiasConstant = -2.0f;
        d.depthBiasSlope = -1.0f;
        d.depthWrite = !wireframe;
        d.depthCompare = wireframe ? VK_COMPARE_OP_LESS_OR_EQUAL : VK_COMPARE_OP_LESS;
        const VkColorComponentFlags rgba =
            VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT | VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
        d.colorFormats = {formats.color};
        d.colorWriteMasks = {rgba};
        if (normalTarget) {
            d.colorFormats.push_back(formats.normal);
            d.colorWriteMasks.push_back(wireframe ? 0 : rgba); // lines leave the normals alone
        }
        d.depthFormat = formats.depth;
        d.layout = descriptors->pipelineLayout();
        return std::make_unique<GraphicsPipeline>(ctx, d);
    }

    void createQueries() {
        timestamps = std::make_unique<Timestamps>(ctx);
        if (ctx.enabledFeatures().pipelineStatisticsQuery) {
            VkQueryPoolCreateInfo qi{};
            qi.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
            qi.queryType = VK_QUERY_TYPE_PIPELINE_STATISTICS;
            qi.queryCount = 1;
            qi.pipelineStatistics = VK_QUERY_PIPELINE_STATISTIC_CLIPPING_INVOCATIONS_BIT |
                                    VK_QUERY_PIPELINE_STATISTIC_TESSELLATION_CONTROL_SHADER_PATCHES_BIT |
                                    VK_QUERY_PIPELINE_STATISTIC_TESSELLATION_EVALUATION_SHADER_INVOCATIONS_BIT;
            DISPMAP_VK_CHECK(ctx.fn(), vkCreateQueryPool, ctx.device(), &qi, nullptr, &statistics);
        }
    }

    void recordUpdate(VkCommandBuffer cmd) {
        const Functions& fn = ctx.fn();
        // Earlier frames' shaders read (and earlier updates wrote) these buffers.
        memoryBarrier(fn, cmd, kShaderStages | VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                      VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
        const GpuParams p = params();
        updateBuffer(fn, cmd, buffer(kParams).handle(), &p, sizeof p);
        std::vector<VkBufferImageCopy> regions;
        for (const Pending& q : pending) {
            updateBuffer(fn, cmd, buffer(q.binding).handle(), q.bytes.data(), q.bytes.size(), q.offset);
            if (q.imageRect.z > 0) {
                // the rectangle's texels, read from the texel buffer (row by row, the image's width)
                VkBufferImageCopy r{};
                const std::size_t texelBytes = packed.format == TexelFormat::Half ? 2 : 4;
                r.bufferOffset = (static_cast<VkDeviceSize>(q.imageRect.y) * static_cast<VkDeviceSize>(packed.width) +
                                  static_cast<VkDeviceSize>(q.imageRect.x)) * texelBytes;
                r.bufferRowLength = static_cast<std::uint32_t>(packed.width);
                r.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
                r.imageOffset = {q.imageRect.x, q.imageRect.y, 0};
                r.imageExtent = {static_cast<std::uint32_t>(q.imageRect.z), static_cast<std::uint32_t>(q.imageRect.w), 1};
                regions.push_back(r);
            }
        }
        pending.clear();
        if (!regions.empty()) {
            // Earlier frames' shaders read the image; the buffer writes above come first.
            memoryBarrier(fn, cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                          VK_ACCESS_TRANSFER_READ_BIT);
            imageBarrier(fn, cmd, packedImage.image(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                         VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, kShaderStages, VK_ACCESS_SHADER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_ACCESS_TRANSFER_WRITE_BIT);
            fn.vkCmdCopyBufferToImage(cmd, buffer(kTexels).handle(), packedImage.image(), VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                                      static_cast<std::uint32_t>(regions.size()), regions.data());
            imageBarrier(fn, cmd, packedImage.image(), VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                         VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                         kShaderStages, VK_ACCESS_SHADER_READ_BIT);
        }
        memoryBarrier(fn, cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, kShaderStages,
                      VK_ACCESS_SHADER_READ_BIT);
    }

    void recordDraw(VkCommandBuffer cmd) const {
        const Functions& fn = ctx.fn();
        const VkViewport viewport{0.0f, 0.0f, float(width), float(height), 0.0f, 1.0f};
        const VkRect2D scissor{{0, 0}, {static_cast<std::uint32_t>(width), static_cast<std::uint32_t>(height)}};
        fn.vkCmdSetViewport(cmd, 0, 1, &viewport);
        fn.vkCmdSetScissor(cmd, 0, 1, &scissor);
        descriptors->bind(cmd);
        const auto batch = static_cast<std::uint32_t>(options.facesPerDraw);
        for (const GraphicsPipeline* p : {fill.get(), wire.get()}) {
            if (!p) continue;
            fn.vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, p->handle());
            for (std::uint32_t first = 0; first < drawCount; first += batch)
                fn.vkCmdDraw(cmd, std::min(batch, drawCount - first), 1, first, 0);
        }
    }

    /// One frame of render(): the engine path into the renderer's own targets.
    void recordFrame(VkCommandBuffer cmd, bool readBack) {
        const Functions& fn = ctx.fn();
        recordUpdate(cmd);
        if (statistics) fn.vkCmdResetQueryPool(cmd, statistics, 0, 1);
        timestamps->begin(cmd);
        if (statistics) fn.vkCmdBeginQuery(cmd, statistics, 0, 0);
        const VkClearColorValue clears[2] = {
            {{float(draw.background.x), float(draw.background.y), float(draw.background.z), 1.0f}}, {{0.0f, 0.0f, 0.0f, 0.0f}}};
        targets->beginRendering(cmd, clears, 1.0f);
        recordDraw(cmd);
        targets->endRendering(cmd);
        if (statistics) fn.vkCmdEndQuery(cmd, statistics, 0);
        timestamps->end(cmd);
        if (readBack) targets->copyToReadBack(cmd);
        memoryBarrier(fn, cmd, VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_TESSELLATION_EVALUATION_SHADER_BIT,
                      VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
                      VK_ACCESS_HOST_READ_BIT);
    }

    void updateControlPoints() {
        const BaseSurface& base = surface.base();
        // As PackedSurface packs them (points to float, w = 0; corner normals with w = the
        // extraordinary-corner flag) and as buildTopology forms the base vertices.
        std::vector<glm::vec4> points;
        points.reserve(base.points().size());
        for (const glm::dvec3& q : base.points()) points.emplace_back(glm::vec3(q), 0.0f);
        const int faces = base.faceCount();
        std::vector<glm::vec4> corners(static_cast<std::size_t>(faces) * 4);
        for (int f = 0; f < faces; ++f)
            for (int c = 0; c < 4; ++c)
                corners[static_cast<std::size_t>(f) * 4 + static_cast<std::size_t>(c)] =
                    glm::vec4(glm::vec3(base.cornerNormal(f, c)), base.isExtraordinaryCorner(f, c) ? 1.0f : 0.0f);
        const std::vector<glm::dvec3> limit = baseVertexLimitPositions(base);
        if (bytesOf(points) != buffer(kPoints).size() || bytesOf(corners) != buffer(kCornerNormals).size() ||
            limit.size() != baseVertices.size())
            throw ArgumentError("updateControlPoints: the surface's point, face or vertex count changed (the renderer keeps its topology)");
        for (std::size_t v = 0; v < limit.size(); ++v)
            baseVertices[v].position = glm::vec4(glm::vec3(limit[v]), baseVertices[v].position.w);
        std::erase_if(pending, [](const Pending& q) { return q.binding == kPoints || q.binding == kCornerNormals || q.binding == kBaseVertices; });
        pending.push_back({kPoints, rawBytes(points), 0});
        pending.push_back({kCornerNormals, rawBytes(corners), 0});
        pending.push_back({kBaseVertices, rawBytes(baseVertices), 0});
    }

    void updateTiles(const std::vector<int>& edited) {
        const TileSet& tiles = surface.tiles();
        for (int t : edited)
            if (t < 0 || t >= tiles.tileCount())
                throw ArgumentError("updateTiles: tile " + std::to_string(t) + " out of range [0, " + std::to_string(tiles.tileCount()) + ")");
        if (draw.effects.technique != Technique::Displaced) return; // no tiles on the device
        for (int t : edited) // every size checked before anything is written
            if (tiles.tiles[static_cast<std::size_t>(t)].size() != packed.records[static_cast<std::size_t>(t)].tileSize)
                throw ArgumentError("updateTiles: tile " + std::to_string(t) + " changed its size (build a new renderer)");
        for (int t : edited) packed.checkTile(t, tiles.tiles[static_cast<std::size_t>(t)]); // half range too, before any write
        for (int t : edited) {
            packed.writeTile(t, tiles.tiles[static_cast<std::size_t>(t)]);
            // The footprint's rows, each one update of the texel buffer (half texels: whole words,
            // so a row may take a neighbour's texel along, unchanged); the image path then copies
            // the footprint from the buffer into the image.
            const glm::ivec4 fp = packed.footprint(t);
            for (int row = fp.y; row < fp.y + fp.w; ++row) {
                const std::size_t first = static_cast<std::size_t>(row) * static_cast<std::size_t>(packed.width) +
                                          static_cast<std::size_t>(fp.x);
                const std::size_t count = static_cast<std::size_t>(fp.z);
                if (packed.format == TexelFormat::Half) {
                    const std::size_t w0 = first / 2, w1 = (first + count + 1) / 2;
                    std::vector<std::uint16_t> halves = packed.halfTexels(2 * w0, 2 * (w1 - w0));
                    halves.resize(2 * (w1 - w0), 0); // past the last texel of the texture: the upload's padding
                    const auto* bytes = reinterpret_cast<const std::uint8_t*>(halves.data());
                    pending.push_back({kTexels, std::vector<std::uint8_t>(bytes, bytes + halves.size() * 2), w0 * 4});
                } else {
                    const auto* bytes = reinterpret_cast<const std::uint8_t*>(packed.texels.data() + first);
                    pending.push_back({kTexels, std::vector<std::uint8_t>(bytes, bytes + count * sizeof(float)), first * sizeof(float)});
                }
            }
            if (imagePath) pending.back().imageRect = fp;
        }
    }
};

SurfaceRenderer::SurfaceRenderer(Context& context, const SurfaceDraw& draw, const DisplacedSurface& surface,
                             const BaselineAtlas* atlas, RendererOptions options)
    : impl_(std::make_unique<Impl>(context, draw, surface, options)) {
    const std::string device = "Vulkan device '" + context.deviceName() + "'";
    if (!context.enabledFeatures().tessellationShader)
        throw VulkanError(device + ": tessellationShader is not enabled, and the renderer draws with tessellation shaders");
    if (!context.dynamicRenderingEnabled())
        throw VulkanError(device + ": dynamic rendering is not enabled (Vulkan 1.3 dynamicRendering or VK_KHR_dynamic_rendering), "
                                   "which the renderer draws with");
    // The evaluation shader declares the capture buffer writable whether the capture is compiled
    // in or not (a specialisation constant cannot change a decoration), so the feature is
    // needed always (the viewer's validation run found it).
    if (!context.enabledFeatures().vertexPipelineStoresAndAtomics)
        throw VulkanError(device + ": vertexPipelineStoresAndAtomics is not enabled; the tessellation evaluation shader "
                                   "declares a writable buffer (the vertex capture)");
    if (draw.effects.wireframe && !context.enabledFeatures().fillModeNonSolid)
        throw VulkanError(device + ": fillModeNonSolid is not enabled, which the wireframe overlay needs");
    const TargetFormats& formats = impl_->formats;
    if (draw.effects.wireframe && formats.normal != VK_FORMAT_UNDEFINED && !context.enabledFeatures().independentBlend)
        throw VulkanError(device + " lacks independentBlend, which the wireframe overlay needs");
    if (options.facesPerDraw < 1) throw ArgumentError("faces per draw must be >= 1");
    checkSurfaceDraw(draw);
    if (options.target) {
        if (formats.color == VK_FORMAT_UNDEFINED) throw ArgumentError("target formats: the colour format must be set");
        if (!isDepthFormat(formats.depth))
            throw ArgumentError("target formats: depth format " + std::to_string(static_cast<int>(formats.depth)) +
                                " is not a depth format (the renderer tests depth)");
        if (formats.depth == VK_FORMAT_D16_UNORM_S8_UINT || formats.depth == VK_FORMAT_D24_UNORM_S8_UINT ||
            formats.depth == VK_FORMAT_D32_SFLOAT_S8_UINT)
            throw ArgumentError("target formats: depth format " + std::to_string(static_cast<int>(formats.depth)) +
                                " has stencil; the pipelines declare a depth-only attachment (D16, X8_D24 or D32)");
        if (options.captureCapacity > 0) throw ArgumentError("the vertex capture is read back by render() only (no target formats)");
        requireFormat(context, formats.color, VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT, "a colour attachment");
        if (formats.normal != VK_FORMAT_UNDEFINED)
            requireFormat(context, formats.normal, VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT, "a normal attachment");
        requireFormat(context, formats.depth, VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT, "a depth attachment");
    }
    const SurfaceEffects& e = draw.effects;
    if (e.technique == Technique::Baseline && !atlas)
        throw ArgumentError("the baseline technique needs its baked atlas (bakeBaseline)");
    if (options.lean && (options.captureCapacity > 0 ||
                         (e.technique == Technique::Displaced && (e.normals != NormalMode::Approximate || e.lod != MipSelection::Off))))
        throw ArgumentError("the lean shaders have approximate normals, LOD off and no capture only");
    if (!(e.maxFactor >= 1.0 && e.maxFactor <= double(context.properties().limits.maxTessellationGenerationLevel)))
        throw ArgumentError("maximum tessellation factor " + std::to_string(e.maxFactor) + " out of the device's range [1, " +
                            std::to_string(context.properties().limits.maxTessellationGenerationLevel) + "]");
    const VkPhysicalDeviceLimits& limits = context.properties().limits;
    if (limits.maxPerStageDescriptorStorageBuffers < kStorageBindings || limits.maxDescriptorSetStorageBuffers < kStorageBindings)
        throw VulkanError("Vulkan device '" + context.deviceName() + "' allows " +
                          std::to_string(std::min(limits.maxPerStageDescriptorStorageBuffers, limits.maxDescriptorSetStorageBuffers)) +
                          " storage buffers per stage; the renderer's shaders bind " + std::to_string(kStorageBindings));
    Impl& m = *impl_;
    m.uploadSurface(e.technique == Technique::Baseline ? atlas : nullptr);
    m.uploadMaps(e.technique == Technique::Baseline ? atlas : nullptr);
    m.uploadPackedImage();
    m.createDescriptors();
    m.fill = m.createPipeline(false);
    if (e.wireframe) m.wire = m.createPipeline(true);
    m.createQueries();
}

SurfaceRenderer::~SurfaceRenderer() = default;

void SurfaceRenderer::setTessValue(double value) {
    if (!std::isfinite(value) || !(value > 0.0)) throw ArgumentError("tessellation value must be finite and > 0");
    impl_->draw.effects.tessValue = value;
}

void SurfaceRenderer::setCamera(const Camera& camera) {
    checkCamera(camera);
    impl_->draw.camera = camera;
}

void SurfaceRenderer::setImageSize(int width, int height) {
    if (width < 1 || height < 1 || width > kMaxImageSize || height > kMaxImageSize)
        throw ArgumentError("image size " + std::to_string(width) + " x " + std::to_string(height) + " out of range [1, " +
                            std::to_string(kMaxImageSize) + "]");
    impl_->width = impl_->draw.width = width;
    impl_->height = impl_->draw.height = height;
}

void SurfaceRenderer::updateControlPoints() { impl_->updateControlPoints(); }
void SurfaceRenderer::updateTiles(const std::vector<int>& tiles) { impl_->updateTiles(tiles); }

void SurfaceRenderer::recordUpdate(VkCommandBuffer cmd) { impl_->recordUpdate(cmd); }

void SurfaceRenderer::recordDraw(VkCommandBuffer cmd) { impl_->recordDraw(cmd); }

glm::dmat4 SurfaceRenderer::viewProjection() const {
    return vulkan::viewProjection(impl_->draw.camera, impl_->width, impl_->height);
}

int SurfaceRenderer::width() const { return impl_->width; }
int SurfaceRenderer::height() const { return impl_->height; }

std::size_t SurfaceRenderer::uploadedBytes() const { return impl_->uploaded; }

RenderedImage SurfaceRenderer::render(int frames, int warmup) {
    Impl& m = *impl_;
    if (m.options.target)
        throw ArgumentError("render() draws into the renderer's own targets; this renderer draws into the caller's "
                            "(RendererOptions::target): use recordUpdate and recordDraw");
    if (frames < 1 || warmup < 0) throw ArgumentError("render: frames must be >= 1 and warm-up frames >= 0");
    const Functions& fn = m.ctx.fn();
    if (!m.targets || m.targets->width() != m.width || m.targets->height() != m.height) {
        m.targets.reset();
        const VkFormat colors[2] = {kColorFormat, kNormalFormat};
        m.targets = std::make_unique<OffscreenTargets>(m.ctx, m.width, m.height, colors, kDepthFormat);
    }
    std::vector<double> times;
    RenderedImage out;
    for (int i = 0; i < warmup + frames; ++i) {
        const bool last = i + 1 == warmup + frames;
        if (last && m.options.captureCapacity > 0) {
            const std::uint32_t zero = 0;
            m.buffer(kCapture).upload(&zero, sizeof zero);
        }
        m.ctx.submitAndWait([&](VkCommandBuffer cmd) { m.recordFrame(cmd, last); });
        if (i >= warmup && m.ctx.timestampsSupported()) times.push_back(m.timestamps->milliseconds());
    }
    out.stats.gpuMs = median(times);
    out.stats.frames = frames;
    if (m.statistics) {
        std::uint64_t s[3] = {0, 0, 0}; // in bit order: clipping, control patches, evaluation invocations
        DISPMAP_VK_CHECK(fn, vkGetQueryPoolResults, m.ctx.device(), m.statistics, 0, 1, sizeof s, s, sizeof s,
                         VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
        out.stats.triangles = s[0];
        out.stats.patches = s[1];
        out.stats.tesInvocations = s[2];
    }
    out.width = m.width;
    out.height = m.height;
    const std::size_t pixels = static_cast<std::size_t>(m.width) * static_cast<std::size_t>(m.height);
    out.rgba.resize(pixels * 4);
    out.normals.resize(pixels);
    out.depth.resize(pixels);
    m.targets->readBack(0).download(out.rgba.data(), out.rgba.size());
    m.targets->readBack(1).download(out.normals.data(), pixels * sizeof(glm::vec4));
    m.targets->readBack(2).download(out.depth.data(), pixels * sizeof(float));
    if (m.options.captureCapacity > 0) {
        std::uint32_t count = 0;
        m.buffer(kCapture).download(&count, sizeof count);
        out.capturedTotal = count;
        const std::uint32_t n = std::min(count, m.options.captureCapacity);
        std::vector<GpuCaptured> raw(n);
        if (n) m.buffer(kCapture).download(raw.data(), n * sizeof(GpuCaptured), kCaptureHeader);
        out.captured.reserve(n);
        for (const GpuCaptured& c : raw)
            out.captured.push_back({static_cast<int>(c.faceUV.x), glm::vec2(c.faceUV.y, c.faceUV.z), glm::vec3(c.position), c.position.w});
    }
    return out;
}

ImageError compareImages(const RenderedImage& test, const RenderedImage& reference) {
    if (test.width != reference.width || test.height != reference.height)
        throw ArgumentError("compareImages: sizes differ (" + std::to_string(test.width) + " x " + std::to_string(test.height) +
                            " vs " + std::to_string(reference.width) + " x " + std::to_string(reference.height) + ")");
    ImageError e;
    const std::size_t pixels = test.normals.size();
    double sq = 0, angleSum = 0;
    std::size_t both = 0, one = 0;
    for (std::size_t i = 0; i < pixels; ++i) {
        for (std::size_t c = 0; c < 3; ++c) {
            const double d = double(test.rgba[4 * i + c]) - double(reference.rgba[4 * i + c]);
            sq += d * d;
        }
        const bool a = test.normals[i].w > 0.5f, b = reference.normals[i].w > 0.5f;
        if (a && b) {
            const glm::dvec3 x(test.normals[i]), y(reference.normals[i]);
            const double angle = std::atan2(glm::length(glm::cross(x, y)), glm::dot(x, y)) * 57.29577951308232;
            angleSum += angle;
            e.maxNormalDeg = std::max(e.maxNormalDeg, angle);
            ++both;
        } else if (a != b) {
            ++one;
        }
    }
    e.rmsColor = pixels ? std::sqrt(sq / double(3 * pixels)) : 0.0;
    e.meanNormalDeg = both ? angleSum / double(both) : 0.0;
    e.coverageMismatch = pixels ? double(one) / double(pixels) : 0.0;
    return e;
}

int enclosedBackground(const RenderedImage& im) {
    const int w = im.width, h = im.height;
    std::vector<char> seen(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), 0);
    std::vector<int> stack;
    const auto bg = [&](int i) { return im.normals[static_cast<std::size_t>(i)].w < 0.5f; };
    for (int x = 0; x < w; ++x) {
        stack.push_back(x);
        stack.push_back((h - 1) * w + x);
    }
    for (int y = 0; y < h; ++y) {
        stack.push_back(y * w);
        stack.push_back(y * w + w - 1);
    }
    while (!stack.empty()) {
        const int i = stack.back();
        stack.pop_back();
        if (seen[static_cast<std::size_t>(i)] || !bg(i)) continue;
        seen[static_cast<std::size_t>(i)] = 1;
        const int x = i % w, y = i / w;
        if (x > 0) stack.push_back(i - 1);
        if (x + 1 < w) stack.push_back(i + 1);
        if (y > 0) stack.push_back(i - w);
        if (y + 1 < h) stack.push_back(i + w);
    }
    int enclosed = 0;
    for (int i = 0; i < w * h; ++i) enclosed += bg(i) && !seen[static_cast<std::size_t>(i)] ? 1 : 0;
    return enclosed;
}

int seeThroughPixels(const RenderedImage& test, const RenderedImage& reference, const Camera& camera, double depthGap) {
    if (test.width != reference.width || test.height != reference.height || test.depth.size() != reference.depth.size() ||
        test.depth.size() != test.normals.size())
        throw ArgumentError("seeThroughPixels: the images differ in size or lack depth");
    // depth = f / (f - n) (1 - n / z) (draw.h): z = n / (1 - depth (f - n) / f)
    const double n = camera.nearPlane, f = camera.farPlane;
    const auto distance = [n, f](float d) { return n / std::max(1.0 - static_cast<double>(d) * (f - n) / f, 1e-300); };
    int count = 0;
    for (std::size_t i = 0; i < test.normals.size(); ++i) {
        if (!(reference.normals[i].w > 0.5f)) continue;
        if (!(test.normals[i].w > 0.5f) || distance(test.depth[i]) > distance(reference.depth[i]) + depthGap) ++count;
    }
    return count;
}

} // namespace dispmap::vulkan
