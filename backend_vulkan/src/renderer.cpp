// SurfaceRenderer: upload of the packed surface and topology, the offscreen render pass, the
// tessellation pipelines of the draw's effects, frames with timestamps and statistics, and
// the read-back. Plain structs with create/destroy functions, destroyed in reverse order.
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

// SPIR-V of shaders/render/*, built by backend_vulkan/CMakeLists.txt.
#include "render_frag_spv.h"
#include "render_frag_lean_spv.h"
#include "render_tesc_spv.h"
#include "render_tesc_lean_spv.h"
#include "render_tese_fe_spv.h"
#include "render_tese_fe_lean_spv.h"
#include "render_tese_int_spv.h"
#include "render_tese_int_lean_spv.h"
#include "render_vert_spv.h"

namespace dispmap::vulkan {

namespace {

// --- The layouts of shaders/render/common.glsl (std430).
struct GpuLight {
    glm::vec4 direction, color;
};
struct GpuParams {
    glm::mat4 viewProj;
    glm::vec4 eye, viewport, tess, albedo, wireColor, atlas;
    glm::ivec4 counts;
    GpuLight lights[4];
};
static_assert(sizeof(GpuParams) == 64 + 6 * 16 + 16 + 4 * 32, "Params block of common.glsl");
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
    kBaselineHeight = kStorageBindings, kBaselineNormal, kBindingCount
};

const VkFormat kColorFormat = VK_FORMAT_R8G8B8A8_UNORM;
const VkFormat kNormalFormat = VK_FORMAT_R32G32B32A32_SFLOAT;
const VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;

struct Image {
    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;
};

Image createImage(Context& ctx, int width, int height, VkFormat format, VkImageUsageFlags usage, VkImageAspectFlags aspect) {
    const Functions& fn = ctx.fn();
    Image im;
    VkImageCreateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
    info.imageType = VK_IMAGE_TYPE_2D;
    info.format = format;
    info.extent = {static_cast<std::uint32_t>(width), static_cast<std::uint32_t>(height), 1};
    info.mipLevels = 1;
    info.arrayLayers = 1;
    info.samples = VK_SAMPLE_COUNT_1_BIT;
    info.tiling = VK_IMAGE_TILING_OPTIMAL;
    info.usage = usage;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    info.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    DISPMAP_VK_CHECK(fn, vkCreateImage, ctx.device(), &info, nullptr, &im.image);
    VkMemoryRequirements needs{};
    fn.vkGetImageMemoryRequirements(ctx.device(), im.image, &needs);
    VkMemoryAllocateInfo alloc{};
    alloc.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    alloc.allocationSize = needs.size;
    alloc.memoryTypeIndex = ctx.findMemoryType(needs.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    DISPMAP_VK_CHECK(fn, vkAllocateMemory, ctx.device(), &alloc, nullptr, &im.memory);
    DISPMAP_VK_CHECK(fn, vkBindImageMemory, ctx.device(), im.image, im.memory, 0);
    VkImageViewCreateInfo view{};
    view.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
    view.image = im.image;
    view.viewType = VK_IMAGE_VIEW_TYPE_2D;
    view.format = format;
    view.subresourceRange = {aspect, 0, 1, 0, 1};
    DISPMAP_VK_CHECK(fn, vkCreateImageView, ctx.device(), &view, nullptr, &im.view);
    return im;
}

void destroyImage(Context& ctx, Image& im) {
    const Functions& fn = ctx.fn();
    if (im.view) fn.vkDestroyImageView(ctx.device(), im.view, nullptr);
    if (im.image) fn.vkDestroyImage(ctx.device(), im.image, nullptr);
    if (im.memory) fn.vkFreeMemory(ctx.device(), im.memory, nullptr);
    im = {};
}

void imageBarrier(const Functions& fn, VkCommandBuffer cmd, VkImage image, VkImageLayout from, VkImageLayout to,
                  VkAccessFlags srcAccess, VkAccessFlags dstAccess, VkPipelineStageFlags srcStage,
                  VkPipelineStageFlags dstStage) {
    VkImageMemoryBarrier b{};
    b.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
    b.srcAccessMask = srcAccess;
    b.dstAccessMask = dstAccess;
    b.oldLayout = from;
    b.newLayout = to;
    b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.image = image;
    b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    fn.vkCmdPipelineBarrier(cmd, srcStage, dstStage, 0, 0, nullptr, 0, nullptr, 1, &b);
}

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
        g.info = glm::ivec4(topo.scale(f), autoAccurate ? 1 : 0, tBits, 0);
        g.chart = atlas ? glm::uvec4(atlas->chartOrigins[static_cast<std::size_t>(f)], 0, 0) : glm::uvec4(0);
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

double median(std::vector<double> v) {
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
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
    int width = 0, height = 0;
    std::uint32_t drawCount = 0;
    std::size_t uploaded = 0;

    std::vector<Buffer> buffers; // by binding, kParams .. kCapture
    Image color, normal, depth, baseHeight, baseNormal;
    VkSampler sampler = VK_NULL_HANDLE;
    VkRenderPass renderPass = VK_NULL_HANDLE;
    VkFramebuffer framebuffer = VK_NULL_HANDLE;
    VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
    VkPipelineLayout layout = VK_NULL_HANDLE;
    VkDescriptorPool pool = VK_NULL_HANDLE;
    VkDescriptorSet set = VK_NULL_HANDLE;
    VkPipeline fill = VK_NULL_HANDLE, wire = VK_NULL_HANDLE;
    VkQueryPool timestamps = VK_NULL_HANDLE, statistics = VK_NULL_HANDLE;
    std::unique_ptr<Buffer> readColor, readNormal, readDepth;

    Impl(Context& c, const SurfaceDraw& s, const DisplacedSurface& surf, RendererOptions o)
        : ctx(c), surface(surf), draw(s), options(o), width(s.width), height(s.height) {}
    ~Impl() { destroy(); }

    void destroy() noexcept {
        const Functions& fn = ctx.fn();
        const VkDevice d = ctx.device();
        fn.vkDeviceWaitIdle(d);
        if (timestamps) fn.vkDestroyQueryPool(d, timestamps, nullptr);
        if (statistics) fn.vkDestroyQueryPool(d, statistics, nullptr);
        if (wire) fn.vkDestroyPipeline(d, wire, nullptr);
        if (fill) fn.vkDestroyPipeline(d, fill, nullptr);
        if (pool) fn.vkDestroyDescriptorPool(d, pool, nullptr);
        if (layout) fn.vkDestroyPipelineLayout(d, layout, nullptr);
        if (setLayout) fn.vkDestroyDescriptorSetLayout(d, setLayout, nullptr);
        if (framebuffer) fn.vkDestroyFramebuffer(d, framebuffer, nullptr);
        if (renderPass) fn.vkDestroyRenderPass(d, renderPass, nullptr);
        if (sampler) fn.vkDestroySampler(d, sampler, nullptr);
        for (Image* im : {&baseNormal, &baseHeight, &depth, &normal, &color}) destroyImage(ctx, *im);
        timestamps = statistics = VK_NULL_HANDLE;
        wire = fill = VK_NULL_HANDLE;
        pool = VK_NULL_HANDLE;
        layout = VK_NULL_HANDLE;
        setLayout = VK_NULL_HANDLE;
        framebuffer = VK_NULL_HANDLE;
        renderPass = VK_NULL_HANDLE;
        sampler = VK_NULL_HANDLE;
        readColor.reset();
        readNormal.reset();
        readDepth.reset();
        buffers.clear();
    }

    Buffer& buffer(Binding b) { return buffers[static_cast<std::size_t>(b)]; }

    template <class T> void upload(Binding b, const std::vector<T>& data) {
        const std::size_t bytes = std::max<std::size_t>(bytesOf(data), 16); // no empty buffers
        buffers[static_cast<std::size_t>(b)] = Buffer(ctx, bytes);
        if (!data.empty()) buffers[static_cast<std::size_t>(b)].upload(data.data(), bytesOf(data));
        uploaded += bytesOf(data);
    }

    void writeParams() {
        GpuParams p{};
        p.viewProj = glm::mat4(vulkan::viewProjection(draw.camera, width, height));
        p.eye = glm::vec4(glm::vec3(draw.camera.eye), 1.0f);
        p.viewport = glm::vec4(float(width), float(height), 0.0f, 0.0f);
        const SurfaceEffects& e = draw.effects;
        p.tess = glm::vec4(float(e.tessValue), float(e.maxFactor), 0.0f, 0.0f);
        p.albedo = glm::vec4(glm::vec3(draw.albedo), float(draw.ambient));
        p.wireColor = glm::vec4(0.05f, 0.05f, 0.05f, 1.0f);
        p.counts = glm::ivec4(static_cast<int>(std::min<std::size_t>(draw.lights.size(), 4)),
                              static_cast<int>(options.captureCapacity), surface.tiles().tileCount() ? packedWidth : 0, 0);
        p.atlas = glm::vec4(float(atlasW), float(atlasH), float(atlasN), 0.0f);
        for (std::size_t i = 0; i < draw.lights.size() && i < 4; ++i) {
            p.lights[i].direction = glm::vec4(glm::vec3(glm::normalize(draw.lights[i].direction)), 0.0f);
            p.lights[i].color = glm::vec4(glm::vec3(draw.lights[i].color), 0.0f);
        }
        buffer(kParams).upload(&p, sizeof p);
    }

    int packedWidth = 0, atlasW = 1, atlasH = 1, atlasN = 1;

    void uploadSurface(const BaselineAtlas* atlas) {
        buffers.clear();
        for (std::uint32_t i = 0; i < kStorageBindings; ++i) buffers.emplace_back(ctx, 16);
        upload(kParams, std::vector<GpuParams>(1));
        const PackedSurface ps(surface.base());
        upload(kPoints, ps.points);
        upload(kPatchIndices, ps.patchIndices);
        upload(kPatches, ps.patches);
        upload(kNodes, ps.nodes);
        upload(kFaceRoots, ps.faceRoots);
        upload(kCornerNormals, ps.cornerNormals);
        if (draw.effects.technique == Technique::Displaced) {
            const PackedTiles packed = surface.tiles().pack();
            packedWidth = packed.width;
            std::vector<glm::uvec4> records;
            for (const PatchRecord& r : packed.records) records.push_back(recordWords(r));
            upload(kTexels, packed.texels);
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
        buffers[kCapture] = Buffer(ctx, kCaptureHeader + std::max<std::size_t>(options.captureCapacity, 1) * sizeof(GpuCaptured));
        if (atlas) {
            atlasW = atlas->width;
            atlasH = atlas->height;
            atlasN = atlas->texelsPerFace;
        }
        writeParams();
    }

    // The baseline's height and normal maps (1 x 1 placeholders for the other techniques:
    // the descriptors must be valid either way).
    void uploadMaps(const BaselineAtlas* atlas) {
        const Functions& fn = ctx.fn();
        VkFormatProperties props{};
        fn.vkGetPhysicalDeviceFormatProperties(ctx.physicalDevice(), VK_FORMAT_R32_SFLOAT, &props);
        if (!(props.optimalTilingFeatures & VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT))
            throw VulkanError("Vulkan device '" + ctx.deviceName() + "' cannot filter R32_SFLOAT textures linearly (baseline height map)");
        const int w = atlas ? atlas->width : 1, h = atlas ? atlas->height : 1;
        std::vector<float> heights = atlas ? atlas->heights : std::vector<float>{0.0f};
        std::vector<std::uint8_t> normals = atlas ? atlas->normals : std::vector<std::uint8_t>{128, 128, 255, 255};
        const VkImageUsageFlags usage = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
        baseHeight = createImage(ctx, w, h, VK_FORMAT_R32_SFLOAT, usage, VK_IMAGE_ASPECT_COLOR_BIT);
        baseNormal = createImage(ctx, w, h, VK_FORMAT_R8G8B8A8_UNORM, usage, VK_IMAGE_ASPECT_COLOR_BIT);
        Buffer staging(ctx, bytesOf(heights) + bytesOf(normals));
        staging.upload(heights.data(), bytesOf(heights));
        staging.upload(normals.data(), bytesOf(normals), bytesOf(heights));
        if (atlas) uploaded += bytesOf(heights) + bytesOf(normals);
        ctx.submitAndWait([&](VkCommandBuffer cmd) {
            VkDeviceSize offset = 0;
            for (VkImage image : {baseHeight.image, baseNormal.image}) {
                imageBarrier(fn, cmd, image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0,
                             VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
                VkBufferImageCopy region{};
                region.bufferOffset = offset;
                region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
                region.imageExtent = {static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h), 1};
                fn.vkCmdCopyBufferToImage(cmd, staging.handle(), image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
                imageBarrier(fn, cmd, image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                             VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_SHADER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                             VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT |
                                 VK_PIPELINE_STAGE_TESSELLATION_EVALUATION_SHADER_BIT);
                offset += bytesOf(heights);
            }
        });
        VkSamplerCreateInfo s{};
        s.sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO;
        s.magFilter = VK_FILTER_LINEAR;
        s.minFilter = VK_FILTER_LINEAR;
        s.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
        s.addressModeU = s.addressModeV = s.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
        s.maxLod = 0.0f;
        DISPMAP_VK_CHECK(fn, vkCreateSampler, ctx.device(), &s, nullptr, &sampler);
    }

    void createTargets() {
        const Functions& fn = ctx.fn();
        const VkImageUsageFlags target = VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
        color = createImage(ctx, width, height, kColorFormat, target | VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT, VK_IMAGE_ASPECT_COLOR_BIT);
        normal = createImage(ctx, width, height, kNormalFormat, target | VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT, VK_IMAGE_ASPECT_COLOR_BIT);
        depth = createImage(ctx, width, height, kDepthFormat, target | VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                            VK_IMAGE_ASPECT_DEPTH_BIT);
        std::array<VkAttachmentDescription, 3> att{};
        const VkFormat formats[3] = {kColorFormat, kNormalFormat, kDepthFormat};
        for (int i = 0; i < 3; ++i) {
            att[static_cast<std::size_t>(i)].format = formats[i];
            att[static_cast<std::size_t>(i)].samples = VK_SAMPLE_COUNT_1_BIT;
            att[static_cast<std::size_t>(i)].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
            att[static_cast<std::size_t>(i)].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
            att[static_cast<std::size_t>(i)].stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
            att[static_cast<std::size_t>(i)].stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
            att[static_cast<std::size_t>(i)].initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
            att[static_cast<std::size_t>(i)].finalLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
        }
        const VkAttachmentReference colorRefs[2] = {{0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL},
                                                    {1, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL}};
        const VkAttachmentReference depthRef{2, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
        VkSubpassDescription sub{};
        sub.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
        sub.colorAttachmentCount = 2;
        sub.pColorAttachments = colorRefs;
        sub.pDepthStencilAttachment = &depthRef;
        // The copies after the pass wait for its attachment writes.
        VkSubpassDependency dep{};
        dep.srcSubpass = 0;
        dep.dstSubpass = VK_SUBPASS_EXTERNAL;
        dep.srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
        dep.dstStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT;
        dep.srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
        dep.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
        VkRenderPassCreateInfo rp{};
        rp.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO;
        rp.attachmentCount = 3;
        rp.pAttachments = att.data();
        rp.subpassCount = 1;
        rp.pSubpasses = &sub;
        rp.dependencyCount = 1;
        rp.pDependencies = &dep;
        DISPMAP_VK_CHECK(fn, vkCreateRenderPass, ctx.device(), &rp, nullptr, &renderPass);
        const VkImageView views[3] = {color.view, normal.view, depth.view};
        VkFramebufferCreateInfo fb{};
        fb.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO;
        fb.renderPass = renderPass;
        fb.attachmentCount = 3;
        fb.pAttachments = views;
        fb.width = static_cast<std::uint32_t>(width);
        fb.height = static_cast<std::uint32_t>(height);
        fb.layers = 1;
        DISPMAP_VK_CHECK(fn, vkCreateFramebuffer, ctx.device(), &fb, nullptr, &framebuffer);
        const std::size_t pixels = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
        readColor = std::make_unique<Buffer>(ctx, pixels * 4);
        readNormal = std::make_unique<Buffer>(ctx, pixels * 16);
        readDepth = std::make_unique<Buffer>(ctx, pixels * 4);
    }

    void createDescriptors() {
        const Functions& fn = ctx.fn();
        std::array<VkDescriptorSetLayoutBinding, kBindingCount> b{};
        for (std::uint32_t i = 0; i < kBindingCount; ++i)
            b[i] = {i, i < kStorageBindings ? VK_DESCRIPTOR_TYPE_STORAGE_BUFFER : VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                    VK_SHADER_STAGE_ALL_GRAPHICS, nullptr};
        VkDescriptorSetLayoutCreateInfo li{};
        li.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
        li.bindingCount = kBindingCount;
        li.pBindings = b.data();
        DISPMAP_VK_CHECK(fn, vkCreateDescriptorSetLayout, ctx.device(), &li, nullptr, &setLayout);
        VkPipelineLayoutCreateInfo pl{};
        pl.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
        pl.setLayoutCount = 1;
        pl.pSetLayouts = &setLayout;
        DISPMAP_VK_CHECK(fn, vkCreatePipelineLayout, ctx.device(), &pl, nullptr, &layout);
        const VkDescriptorPoolSize sizes[2] = {{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, kStorageBindings},
                                               {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 2}};
        VkDescriptorPoolCreateInfo pi{};
        pi.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
        pi.maxSets = 1;
        pi.poolSizeCount = 2;
        pi.pPoolSizes = sizes;
        DISPMAP_VK_CHECK(fn, vkCreateDescriptorPool, ctx.device(), &pi, nullptr, &pool);
        VkDescriptorSetAllocateInfo ai{};
        ai.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
        ai.descriptorPool = pool;
        ai.descriptorSetCount = 1;
        ai.pSetLayouts = &setLayout;
        DISPMAP_VK_CHECK(fn, vkAllocateDescriptorSets, ctx.device(), &ai, &set);
        std::array<VkDescriptorBufferInfo, kStorageBindings> infos{};
        std::array<VkDescriptorImageInfo, 2> images{};
        std::array<VkWriteDescriptorSet, kBindingCount> writes{};
        for (std::uint32_t i = 0; i < kBindingCount; ++i) {
            writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
            writes[i].dstSet = set;
            writes[i].dstBinding = i;
            writes[i].descriptorCount = 1;
            if (i < kStorageBindings) {
                infos[i] = {buffers[i].handle(), 0, VK_WHOLE_SIZE};
                writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
                writes[i].pBufferInfo = &infos[i];
            } else {
                images[i - kStorageBindings] = {sampler, i == kBaselineHeight ? baseHeight.view : baseNormal.view,
                                                VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
                writes[i].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
                writes[i].pImageInfo = &images[i - kStorageBindings];
            }
        }
        fn.vkUpdateDescriptorSets(ctx.device(), kBindingCount, writes.data(), 0, nullptr);
    }

    VkPipeline createPipeline(bool wireframe) {
        const Functions& fn = ctx.fn();
        const SurfaceEffects& e = draw.effects;
        const bool displaced = e.technique == Technique::Displaced;
        const std::uint32_t spec[6] = {
            static_cast<std::uint32_t>(techniqueIndex(e.technique)),
            static_cast<std::uint32_t>(displaced ? normalsIndex(e.normals) : 0),
            static_cast<std::uint32_t>(displaced ? lodIndex(e.lod) : 0),
            static_cast<std::uint32_t>(methodIndex(e.tessMethod)),
            options.captureCapacity > 0 ? 1u : 0u,
            wireframe ? 1u : 0u};
        std::array<VkSpecializationMapEntry, 6> entries{};
        for (std::uint32_t i = 0; i < 6; ++i) entries[i] = {i, i * 4, 4};
        VkSpecializationInfo si{6, entries.data(), sizeof spec, spec};

        const bool integer = e.spacing == Spacing::Integer;
        const bool lean = options.lean;
        struct Stage {
            VkShaderStageFlagBits stage;
            const std::uint32_t* code;
            std::size_t bytes;
        };
#define DISPMAP_STAGE(bit, name) Stage{bit, name, sizeof(name)}
        const Stage stages[4] = {
            DISPMAP_STAGE(VK_SHADER_STAGE_VERTEX_BIT, render_vert_spv),
            lean ? DISPMAP_STAGE(VK_SHADER_STAGE_TESSELLATION_CONTROL_BIT, render_tesc_lean_spv)
                 : DISPMAP_STAGE(VK_SHADER_STAGE_TESSELLATION_CONTROL_BIT, render_tesc_spv),
            integer ? (lean ? DISPMAP_STAGE(VK_SHADER_STAGE_TESSELLATION_EVALUATION_BIT, render_tese_int_lean_spv)
                            : DISPMAP_STAGE(VK_SHADER_STAGE_TESSELLATION_EVALUATION_BIT, render_tese_int_spv))
                    : (lean ? DISPMAP_STAGE(VK_SHADER_STAGE_TESSELLATION_EVALUATION_BIT, render_tese_fe_lean_spv)
                            : DISPMAP_STAGE(VK_SHADER_STAGE_TESSELLATION_EVALUATION_BIT, render_tese_fe_spv)),
            lean ? DISPMAP_STAGE(VK_SHADER_STAGE_FRAGMENT_BIT, render_frag_lean_spv)
                 : DISPMAP_STAGE(VK_SHADER_STAGE_FRAGMENT_BIT, render_frag_spv)};
#undef DISPMAP_STAGE
        std::array<VkShaderModule, 4> modules{};
        std::array<VkPipelineShaderStageCreateInfo, 4> infos{};
        VkPipeline pipeline = VK_NULL_HANDLE;
        try {
            for (std::size_t i = 0; i < 4; ++i) {
                VkShaderModuleCreateInfo mi{};
                mi.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
                mi.codeSize = stages[i].bytes;
                mi.pCode = stages[i].code;
                DISPMAP_VK_CHECK(fn, vkCreateShaderModule, ctx.device(), &mi, nullptr, &modules[i]);
                infos[i].sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
                infos[i].stage = stages[i].stage;
                infos[i].module = modules[i];
                infos[i].pName = "main";
                infos[i].pSpecializationInfo = &si;
            }
            VkPipelineVertexInputStateCreateInfo vi{};
            vi.sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO;
            VkPipelineInputAssemblyStateCreateInfo ia{};
            ia.sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO;
            ia.topology = VK_PRIMITIVE_TOPOLOGY_PATCH_LIST;
            VkPipelineTessellationStateCreateInfo ts{};
            ts.sType = VK_STRUCTURE_TYPE_PIPELINE_TESSELLATION_STATE_CREATE_INFO;
            ts.patchControlPoints = 1;
            VkPipelineViewportStateCreateInfo vp{};
            vp.sType = VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO;
            vp.viewportCount = 1;
            vp.scissorCount = 1;
            VkPipelineRasterizationStateCreateInfo rs{};
            rs.sType = VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO;
            rs.polygonMode = wireframe ? VK_POLYGON_MODE_LINE : VK_POLYGON_MODE_FILL;
            rs.cullMode = VK_CULL_MODE_NONE; // open meshes and holes show their inside
            rs.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
            rs.lineWidth = 1.0f;
            rs.depthBiasEnable = wireframe ? VK_TRUE : VK_FALSE;
            rs.depthBiasConstantFactor = -2.0f;
            rs.depthBiasSlopeFactor = -1.0f;
            VkPipelineMultisampleStateCreateInfo ms{};
            ms.sType = VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO;
            ms.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
            VkPipelineDepthStencilStateCreateInfo ds{};
            ds.sType = VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO;
            ds.depthTestEnable = VK_TRUE;
            ds.depthWriteEnable = wireframe ? VK_FALSE : VK_TRUE;
            ds.depthCompareOp = wireframe ? VK_COMPARE_OP_LESS_OR_EQUAL : VK_COMPARE_OP_LESS;
            std::array<VkPipelineColorBlendAttachmentState, 2> blend{};
            blend[0].colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT | VK_COLOR_COMPONENT_B_BIT |
                                      VK_COLOR_COMPONENT_A_BIT;
            blend[1].colorWriteMask = wireframe ? 0 : blend[0].colorWriteMask; // lines leave the normals alone
            VkPipelineColorBlendStateCreateInfo cb{};
            cb.sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO;
            cb.attachmentCount = 2;
            cb.pAttachments = blend.data();
            const VkDynamicState dyn[2] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
            VkPipelineDynamicStateCreateInfo dy{};
            dy.sType = VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO;
            dy.dynamicStateCount = 2;
            dy.pDynamicStates = dyn;
            VkGraphicsPipelineCreateInfo gi{};
            gi.sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO;
            gi.stageCount = 4;
            gi.pStages = infos.data();
            gi.pVertexInputState = &vi;
            gi.pInputAssemblyState = &ia;
            gi.pTessellationState = &ts;
            gi.pViewportState = &vp;
            gi.pRasterizationState = &rs;
            gi.pMultisampleState = &ms;
            gi.pDepthStencilState = &ds;
            gi.pColorBlendState = &cb;
            gi.pDynamicState = &dy;
            gi.layout = layout;
            gi.renderPass = renderPass;
            DISPMAP_VK_CHECK(fn, vkCreateGraphicsPipelines, ctx.device(), VK_NULL_HANDLE, 1, &gi, nullptr, &pipeline);
        } catch (...) {
            for (VkShaderModule m : modules)
                if (m) fn.vkDestroyShaderModule(ctx.device(), m, nullptr);
            throw;
        }
        for (VkShaderModule m : modules) fn.vkDestroyShaderModule(ctx.device(), m, nullptr);
        return pipeline;
    }

    void createQueries() {
        const Functions& fn = ctx.fn();
        if (ctx.timestampsSupported()) {
            VkQueryPoolCreateInfo qi{};
            qi.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
            qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
            qi.queryCount = 2;
            DISPMAP_VK_CHECK(fn, vkCreateQueryPool, ctx.device(), &qi, nullptr, &timestamps);
        }
        if (ctx.enabledFeatures().pipelineStatisticsQuery) {
            VkQueryPoolCreateInfo qi{};
            qi.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
            qi.queryType = VK_QUERY_TYPE_PIPELINE_STATISTICS;
            qi.queryCount = 1;
            qi.pipelineStatistics = VK_QUERY_PIPELINE_STATISTIC_CLIPPING_INVOCATIONS_BIT |
                                    VK_QUERY_PIPELINE_STATISTIC_TESSELLATION_CONTROL_SHADER_PATCHES_BIT |
                                    VK_QUERY_PIPELINE_STATISTIC_TESSELLATION_EVALUATION_SHADER_INVOCATIONS_BIT;
            DISPMAP_VK_CHECK(fn, vkCreateQueryPool, ctx.device(), &qi, nullptr, &statistics);
        }
    }

    void record(VkCommandBuffer cmd, bool readBack) {
        const Functions& fn = ctx.fn();
        if (timestamps) fn.vkCmdResetQueryPool(cmd, timestamps, 0, 2);
        if (statistics) fn.vkCmdResetQueryPool(cmd, statistics, 0, 1);
        if (timestamps) fn.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, timestamps, 0);
        if (statistics) fn.vkCmdBeginQuery(cmd, statistics, 0, 0);
        std::array<VkClearValue, 3> clear{};
        clear[0].color = {{float(draw.background.x), float(draw.background.y), float(draw.background.z), 1.0f}};
        clear[1].color = {{0.0f, 0.0f, 0.0f, 0.0f}};
        clear[2].depthStencil = {1.0f, 0};
        VkRenderPassBeginInfo rb{};
        rb.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO;
        rb.renderPass = renderPass;
        rb.framebuffer = framebuffer;
        rb.renderArea = {{0, 0}, {static_cast<std::uint32_t>(width), static_cast<std::uint32_t>(height)}};
        rb.clearValueCount = 3;
        rb.pClearValues = clear.data();
        fn.vkCmdBeginRenderPass(cmd, &rb, VK_SUBPASS_CONTENTS_INLINE);
        const VkViewport viewport{0.0f, 0.0f, float(width), float(height), 0.0f, 1.0f};
        const VkRect2D scissor{{0, 0}, {static_cast<std::uint32_t>(width), static_cast<std::uint32_t>(height)}};
        fn.vkCmdSetViewport(cmd, 0, 1, &viewport);
        fn.vkCmdSetScissor(cmd, 0, 1, &scissor);
        fn.vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout, 0, 1, &set, 0, nullptr);
        const auto batch = static_cast<std::uint32_t>(options.facesPerDraw);
        for (VkPipeline p : {fill, wire}) {
            if (!p) continue;
            fn.vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, p);
            for (std::uint32_t first = 0; first < drawCount; first += batch)
                fn.vkCmdDraw(cmd, std::min(batch, drawCount - first), 1, first, 0);
        }
        fn.vkCmdEndRenderPass(cmd);
        if (statistics) fn.vkCmdEndQuery(cmd, statistics, 0);
        if (timestamps) fn.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, timestamps, 1);
        if (readBack) {
            VkBufferImageCopy region{};
            region.imageExtent = {static_cast<std::uint32_t>(width), static_cast<std::uint32_t>(height), 1};
            region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
            fn.vkCmdCopyImageToBuffer(cmd, color.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, readColor->handle(), 1, &region);
            fn.vkCmdCopyImageToBuffer(cmd, normal.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, readNormal->handle(), 1, &region);
            region.imageSubresource.aspectMask = VK_IMAGE_ASPECT_DEPTH_BIT;
            fn.vkCmdCopyImageToBuffer(cmd, depth.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, readDepth->handle(), 1, &region);
        }
        VkMemoryBarrier toHost{};
        toHost.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
        toHost.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_WRITE_BIT;
        toHost.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
        fn.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_TESSELLATION_EVALUATION_SHADER_BIT,
                                VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &toHost, 0, nullptr, 0, nullptr);
    }
};

SurfaceRenderer::SurfaceRenderer(Context& context, const SurfaceDraw& draw, const DisplacedSurface& surface,
                             const BaselineAtlas* atlas, RendererOptions options)
    : impl_(std::make_unique<Impl>(context, draw, surface, options)) {
    if (!context.enabledFeatures().tessellationShader)
        throw VulkanError("Vulkan device '" + context.deviceName() + "' has no tessellation shaders");
    if (options.captureCapacity > 0 && !context.enabledFeatures().vertexPipelineStoresAndAtomics)
        throw VulkanError("Vulkan device '" + context.deviceName() +
                          "' cannot store from the tessellation evaluation shader (vertexPipelineStoresAndAtomics), "
                          "which the vertex capture needs");
    if (draw.effects.wireframe && !context.enabledFeatures().independentBlend)
        throw VulkanError("Vulkan device '" + context.deviceName() + "' lacks independentBlend, which the wireframe overlay needs");
    if (options.facesPerDraw < 1) throw ArgumentError("faces per draw must be >= 1");
    checkSurfaceDraw(draw);
    const SurfaceEffects& e = draw.effects;
    if (e.technique == Technique::Baseline && !atlas)
        throw ArgumentError("the baseline technique needs its baked atlas (bakeBaseline)");
    if (options.lean && (options.captureCapacity > 0 ||
                         (e.technique == Technique::Displaced && (e.normals != NormalMode::Approximate || e.lod != MipSelection::Off))))
        throw ArgumentError("the lean shaders have approximate normals, LOD off and no capture only");
    if (!(e.maxFactor >= 1.0 && e.maxFactor <= double(context.properties().limits.maxTessellationGenerationLevel)))
        throw ArgumentError("maximum tessellation factor " + std::to_string(e.maxFactor) + " out of the device's range [1, " +
                            std::to_string(context.properties().limits.maxTessellationGenerationLevel) + "]");
    Impl& m = *impl_;
    m.uploadSurface(e.technique == Technique::Baseline ? atlas : nullptr);
    m.uploadMaps(e.technique == Technique::Baseline ? atlas : nullptr);
    m.createTargets();
    m.createDescriptors();
    m.fill = m.createPipeline(false);
    if (e.wireframe) m.wire = m.createPipeline(true);
    m.createQueries();
}

SurfaceRenderer::~SurfaceRenderer() = default;

void SurfaceRenderer::setTessValue(double value) {
    if (!std::isfinite(value) || !(value > 0.0)) throw ArgumentError("tessellation value must be finite and > 0");
    impl_->draw.effects.tessValue = value;
    impl_->writeParams();
}

void SurfaceRenderer::setCamera(const Camera& camera) {
    checkCamera(camera);
    impl_->draw.camera = camera;
    impl_->writeParams();
}

glm::dmat4 SurfaceRenderer::viewProjection() const {
    return vulkan::viewProjection(impl_->draw.camera, impl_->width, impl_->height);
}

std::size_t SurfaceRenderer::uploadedBytes() const { return impl_->uploaded; }

RenderedImage SurfaceRenderer::render(int frames, int warmup) {
    if (frames < 1 || warmup < 0) throw ArgumentError("render: frames must be >= 1 and warm-up frames >= 0");
    Impl& m = *impl_;
    const Functions& fn = m.ctx.fn();
    std::vector<double> times;
    RenderedImage out;
    for (int i = 0; i < warmup + frames; ++i) {
        const bool last = i + 1 == warmup + frames;
        if (last && m.options.captureCapacity > 0) {
            const std::uint32_t zero = 0;
            m.buffer(kCapture).upload(&zero, sizeof zero);
        }
        m.ctx.submitAndWait([&](VkCommandBuffer cmd) { m.record(cmd, last); });
        if (i >= warmup && m.timestamps) {
            std::uint64_t t[2] = {0, 0};
            DISPMAP_VK_CHECK(fn, vkGetQueryPoolResults, m.ctx.device(), m.timestamps, 0, 2, sizeof t, t, sizeof(std::uint64_t),
                             VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
            times.push_back(double(t[1] - t[0]) * m.ctx.timestampPeriodNs() * 1e-6);
        }
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
    m.readColor->download(out.rgba.data(), out.rgba.size());
    m.readNormal->download(out.normals.data(), pixels * sizeof(glm::vec4));
    m.readDepth->download(out.depth.data(), pixels * sizeof(float));
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

} // namespace dispmap::vulkan
