// The engine-facing renderer API: recordUpdate / recordDraw into the test's own images and
// dynamic rendering (colour only in BGRA, and colour + normal), a Context wrapping another
// context's device (ExternalDevice), animation of the cage through updateControlPoints, and
// the errors of the engine mode. Every image is compared bit for bit with the offscreen
// render() of the same draw.
#include <cmath>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include <catch2/catch.hpp>

#include "dispmap/scene/scene.h"
#include "dispmap/surface/builtin.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/tile_builder.h"
#include "dispmap/vulkan/renderer.h"
#include "gpu_support.h"

using namespace dispmap;
using dispmap::vulkan::Context;
using dispmap::vulkan::RenderedImage;
using dispmap::vulkan::RendererOptions;
using dispmap::vulkan::SurfaceRenderer;
using dispmap::vulkan::TargetFormats;

namespace {

BaseSurfaceOptions isolated(int level) {
    BaseSurfaceOptions o;
    o.isolationLevel = level;
    return o;
}

/// The default cage with the default waves, built the way an engine would (no Scene).
struct Surface {
    explicit Surface(int isolation = 6) : base(mesh, isolated(isolation)) {}
    ControlMesh mesh = builtin::defaultMesh();
    TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 4), FunctionSource(builtin::defaultDisplacement));
    BaseSurface base;
    DisplacedSurface surface{base, tiles};
};

SurfaceDraw smallDraw(int width = 96, int height = 72) {
    SurfaceDraw d = defaultScene(); // camera, lights and effects of the default scene
    d.width = width;
    d.height = height;
    d.background = {0.1, 0.2, 0.3};
    d.effects.tessValue = 6;
    return d;
}

/// An image of the test's own (device-local, optimal tiling) with a view.
class TestImage {
  public:
    TestImage(Context& ctx, int w, int h, VkFormat format, VkImageUsageFlags usage, VkImageAspectFlags aspect)
        : ctx_(ctx), aspect_(aspect) {
        const vulkan::Functions& fn = ctx.fn();
        VkImageCreateInfo info{};
        info.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
        info.imageType = VK_IMAGE_TYPE_2D;
        info.format = format;
        info.extent = {static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h), 1};
        info.mipLevels = info.arrayLayers = 1;
        info.samples = VK_SAMPLE_COUNT_1_BIT;
        info.tiling = VK_IMAGE_TILING_OPTIMAL;
        info.usage = usage;
        DISPMAP_VK_CHECK(fn, vkCreateImage, ctx.device(), &info, nullptr, &image);
        VkMemoryRequirements needs{};
        fn.vkGetImageMemoryRequirements(ctx.device(), image, &needs);
        VkMemoryAllocateInfo alloc{};
        alloc.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
        alloc.allocationSize = needs.size;
        alloc.memoryTypeIndex = ctx.findMemoryType(needs.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
        DISPMAP_VK_CHECK(fn, vkAllocateMemory, ctx.device(), &alloc, nullptr, &memory);
        DISPMAP_VK_CHECK(fn, vkBindImageMemory, ctx.device(), image, memory, 0);
        VkImageViewCreateInfo vi{};
        vi.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
        vi.image = image;
        vi.viewType = VK_IMAGE_VIEW_TYPE_2D;
        vi.format = format;
        vi.subresourceRange = {aspect, 0, 1, 0, 1};
        DISPMAP_VK_CHECK(fn, vkCreateImageView, ctx.device(), &vi, nullptr, &view);
    }
    ~TestImage() {
        ctx_.fn().vkDestroyImageView(ctx_.device(), view, nullptr);
        ctx_.fn().vkDestroyImage(ctx_.device(), image, nullptr);
        ctx_.fn().vkFreeMemory(ctx_.device(), memory, nullptr);
    }
    TestImage(const TestImage&) = delete;
    TestImage& operator=(const TestImage&) = delete;

    void barrier(VkCommandBuffer cmd, VkImageLayout from, VkImageLayout to, VkPipelineStageFlags src, VkAccessFlags srcAccess,
                 VkPipelineStageFlags dst, VkAccessFlags dstAccess) const {
        VkImageMemoryBarrier b{};
        b.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
        b.srcAccessMask = srcAccess;
        b.dstAccessMask = dstAccess;
        b.oldLayout = from;
        b.newLayout = to;
        b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
        b.image = image;
        b.subresourceRange = {aspect_, 0, 1, 0, 1};
        ctx_.fn().vkCmdPipelineBarrier(cmd, src, dst, 0, 0, nullptr, 0, nullptr, 1, &b);
    }

    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;

  private:
    Context& ctx_;
    VkImageAspectFlags aspect_;
};

struct EngineImage {
    std::vector<std::uint8_t> color; ///< as the colour format stores it (BGRA or RGBA)
    std::vector<glm::vec4> normals;  ///< with a normal attachment
};

/// One frame the way an engine records it: recordUpdate, then its own vkCmdBeginRendering
/// (its images, clears and layouts), recordDraw, vkCmdEndRendering, then a copy to the host.
EngineImage drawAsEngine(Context& ctx, SurfaceRenderer& r, const TargetFormats& f, const glm::dvec3& background) {
    const vulkan::Functions& fn = ctx.fn();
    const int w = r.width(), h = r.height();
    const auto pixels = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
    const VkImageUsageFlags colorUsage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
    const TestImage color(ctx, w, h, f.color, colorUsage, VK_IMAGE_ASPECT_COLOR_BIT);
    std::optional<TestImage> normal;
    if (f.normal != VK_FORMAT_UNDEFINED) normal.emplace(ctx, w, h, f.normal, colorUsage, VK_IMAGE_ASPECT_COLOR_BIT);
    const TestImage depth(ctx, w, h, f.depth, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT, VK_IMAGE_ASPECT_DEPTH_BIT);
    vulkan::Buffer readColor(ctx, pixels * 4), readNormal(ctx, pixels * 16);
    ctx.submitAndWait([&](VkCommandBuffer cmd) {
        r.recordUpdate(cmd);
        std::vector<const TestImage*> colors{&color};
        if (normal) colors.push_back(&*normal);
        for (const TestImage* c : colors)
            c->barrier(cmd, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0,
                       VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT);
        depth.barrier(cmd, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT,
                      0, VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                      VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
        std::vector<VkRenderingAttachmentInfo> attachments(colors.size());
        for (std::size_t i = 0; i < colors.size(); ++i) {
            attachments[i].sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO;
            attachments[i].imageView = colors[i]->view;
            attachments[i].imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
            attachments[i].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
            attachments[i].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
            attachments[i].clearValue.color = i == 0 ? VkClearColorValue{{float(background.x), float(background.y), float(background.z), 1.0f}}
                                                     : VkClearColorValue{{0.0f, 0.0f, 0.0f, 0.0f}};
        }
        VkRenderingAttachmentInfo depthAttachment{};
        depthAttachment.sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO;
        depthAttachment.imageView = depth.view;
        depthAttachment.imageLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
        depthAttachment.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
        depthAttachment.storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
        depthAttachment.clearValue.depthStencil = {1.0f, 0};
        VkRenderingInfo info{};
        info.sType = VK_STRUCTURE_TYPE_RENDERING_INFO;
        info.renderArea = {{0, 0}, {static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h)}};
        info.layerCount = 1;
        info.colorAttachmentCount = static_cast<std::uint32_t>(attachments.size());
        info.pColorAttachments = attachments.data();
        info.pDepthAttachment = &depthAttachment;
        fn.vkCmdBeginRendering(cmd, &info);
        r.recordDraw(cmd);
        fn.vkCmdEndRendering(cmd);
        VkBufferImageCopy region{};
        region.imageExtent = {static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h), 1};
        region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        const vulkan::Buffer* reads[2] = {&readColor, &readNormal};
        for (std::size_t i = 0; i < colors.size(); ++i) {
            colors[i]->barrier(cmd, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                               VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT,
                               VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
            fn.vkCmdCopyImageToBuffer(cmd, colors[i]->image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, reads[i]->handle(), 1, &region);
        }
        VkMemoryBarrier toHost{};
        toHost.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
        toHost.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
        toHost.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
        fn.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &toHost, 0, nullptr, 0, nullptr);
    });
    EngineImage out;
    out.color.resize(pixels * 4);
    readColor.download(out.color.data(), out.color.size());
    if (normal) {
        out.normals.resize(pixels);
        readNormal.download(out.normals.data(), pixels * sizeof(glm::vec4));
    }
    return out;
}

std::vector<std::uint8_t> bgraToRgba(std::vector<std::uint8_t> v) {
    for (std::size_t i = 0; i + 3 < v.size(); i += 4) std::swap(v[i], v[i + 2]);
    return v;
}

bool sameBits(const std::vector<glm::vec4>& a, const std::vector<glm::vec4>& b) {
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(glm::vec4)) == 0);
}

std::size_t coveredPixels(const RenderedImage& im) {
    std::size_t n = 0;
    for (const glm::vec4& v : im.normals) n += v.w > 0.5f ? 1 : 0;
    return n;
}

constexpr TargetFormats kBgraOnly{VK_FORMAT_B8G8R8A8_UNORM, VK_FORMAT_UNDEFINED, VK_FORMAT_D32_SFLOAT};
constexpr TargetFormats kRgbaNormal{VK_FORMAT_R8G8B8A8_UNORM, VK_FORMAT_R32G32B32A32_SFLOAT, VK_FORMAT_D32_SFLOAT};

} // namespace

TEST_CASE("engine: recordDraw into the caller's attachments equals the offscreen render bit for bit", "[engine]") {
    Context& ctx = dmgpu::context();
    REQUIRE(ctx.dynamicRenderingEnabled());
    const Surface s;
    for (const bool wireframe : {false, true}) {
        SurfaceDraw draw = smallDraw();
        draw.effects.wireframe = wireframe;
        SurfaceRenderer offscreen(ctx, draw, s.surface);
        RendererOptions bgra, rgba;
        bgra.target = kBgraOnly;
        rgba.target = kRgbaNormal;
        SurfaceRenderer colorOnly(ctx, draw, s.surface, nullptr, bgra), withNormal(ctx, draw, s.surface, nullptr, rgba);
        // Two views: the second frame's parameters come through recordUpdate alone.
        Camera second = draw.camera;
        second.eye = glm::dvec3(-3.1, 1.2, -2.4);
        for (const Camera& cam : {draw.camera, second}) {
            for (SurfaceRenderer* r : {&offscreen, &colorOnly, &withNormal}) r->setCamera(cam);
            const RenderedImage ref = offscreen.render(1, 0);
            INFO("wireframe " << wireframe << ", eye " << cam.eye.x << "," << cam.eye.y << "," << cam.eye.z);
            REQUIRE(coveredPixels(ref) > ref.normals.size() / 20);
            const EngineImage a = drawAsEngine(ctx, colorOnly, kBgraOnly, draw.background);
            CHECK(bgraToRgba(a.color) == ref.rgba);
            const EngineImage b = drawAsEngine(ctx, withNormal, kRgbaNormal, draw.background);
            CHECK(b.color == ref.rgba);
            CHECK(sameBits(b.normals, ref.normals));
        }
    }
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("engine: a Context wrapping another context's device renders the same images", "[engine]") {
    Context& shared = dmgpu::context();
    const Surface s;
    const SurfaceDraw draw = smallDraw();
    const RenderedImage ref = SurfaceRenderer(shared, draw, s.surface).render(1, 0);
    const vulkan::ExternalDevice external{shared.fn().vkGetInstanceProcAddr, shared.instance(), shared.physicalDevice(),
                                          shared.device(), shared.queue(), shared.queueFamily(), shared.enabledFeatures(),
                                          shared.dynamicRenderingEnabled()};
    {
        Context wrapped(external);
        CHECK(wrapped.isExternal());
        CHECK(wrapped.device() == shared.device());
        CHECK(wrapped.deviceName() == shared.deviceName());
        CHECK(wrapped.dynamicRenderingEnabled());
        CHECK_FALSE(wrapped.validationEnabled()); // the caller's instance reports (here: the shared messenger)
        const RenderedImage im = SurfaceRenderer(wrapped, draw, s.surface).render(1, 0);
        CHECK(im.rgba == ref.rgba);
        CHECK(sameBits(im.normals, ref.normals));
        CHECK(im.depth == ref.depth);
        RendererOptions o;
        o.target = kBgraOnly;
        SurfaceRenderer engine(wrapped, draw, s.surface, nullptr, o);
        CHECK(bgraToRgba(drawAsEngine(wrapped, engine, kBgraOnly, draw.background).color) == ref.rgba);
    }
    // The wrapped Context destroyed nothing of the caller's: the device still renders.
    CHECK(SurfaceRenderer(shared, draw, s.surface).render(1, 0).rgba == ref.rgba);

    // What the caller did not enable is a clear error when a renderer needs it.
    vulkan::ExternalDevice noTessellation = external;
    noTessellation.enabledFeatures.tessellationShader = VK_FALSE;
    Context withoutTessellation(noTessellation);
    CHECK_THROWS_AS(SurfaceRenderer(withoutTessellation, draw, s.surface), vulkan::VulkanError);
    CHECK_THROWS_WITH(SurfaceRenderer(withoutTessellation, draw, s.surface), Catch::Contains("tessellationShader is not enabled"));
    vulkan::ExternalDevice noDynamicRendering = external;
    noDynamicRendering.dynamicRendering = false;
    Context withoutDynamicRendering(noDynamicRendering);
    CHECK_THROWS_WITH(SurfaceRenderer(withoutDynamicRendering, draw, s.surface), Catch::Contains("dynamic rendering is not enabled"));
    vulkan::ExternalDevice noStores = external; // the evaluation shader's writable capture buffer
    noStores.enabledFeatures.vertexPipelineStoresAndAtomics = VK_FALSE;
    Context withoutStores(noStores);
    CHECK_THROWS_WITH(SurfaceRenderer(withoutStores, draw, s.surface), Catch::Contains("vertexPipelineStoresAndAtomics is not enabled"));
    vulkan::ExternalDevice noLines = external;
    noLines.enabledFeatures.fillModeNonSolid = VK_FALSE;
    Context withoutLines(noLines);
    SurfaceDraw wired = draw;
    wired.effects.wireframe = true;
    CHECK_THROWS_WITH(SurfaceRenderer(withoutLines, wired, s.surface), Catch::Contains("fillModeNonSolid is not enabled"));
    // Missing handles and a bad queue family are refused by the Context itself.
    vulkan::ExternalDevice noDevice = external;
    noDevice.device = VK_NULL_HANDLE;
    CHECK_THROWS_WITH(Context(noDevice), Catch::Contains("ExternalDevice::device is null"));
    vulkan::ExternalDevice noLoader = external;
    noLoader.getInstanceProcAddr = nullptr;
    CHECK_THROWS_AS(Context(noLoader), vulkan::VulkanError);
    vulkan::ExternalDevice badFamily = external;
    badFamily.queueFamily = 99;
    CHECK_THROWS_WITH(Context(badFamily), Catch::Contains("queueFamily 99 out of range"));
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("engine: a moved cage through updateControlPoints renders what a surface built on the moved cage renders", "[engine]") {
    // Isolation 9: more than 64 KiB of points, written by vkCmdUpdateBuffer in pieces.
    const int isolation = GENERATE(6, 9);
    Context& ctx = dmgpu::context();
    Surface s(isolation);
    if (isolation == 9) REQUIRE(s.base.points().size() * sizeof(glm::vec4) > 65536);
    const SurfaceDraw draw = smallDraw();
    SurfaceRenderer animated(ctx, draw, s.surface);
    RendererOptions o;
    o.target = kRgbaNormal;
    SurfaceRenderer engine(ctx, draw, s.surface, nullptr, o);
    const RenderedImage before = animated.render(1, 0);
    const std::size_t uploaded = animated.uploadedBytes();

    // A smooth deformation of every cage vertex (extraordinary ones, N-gons' corners).
    MeshDescription moved = s.mesh.description();
    for (glm::dvec3& p : moved.positions)
        p = 1.1 * p + 0.2 * glm::dvec3(std::sin(2.0 * p.y), std::sin(1.5 * p.z + 0.3), std::cos(2.5 * p.x));
    s.base.setControlPoints(moved.positions);
    animated.updateControlPoints();
    engine.updateControlPoints();
    const RenderedImage after = animated.render(1, 0);
    const EngineImage engineAfter = drawAsEngine(ctx, engine, kRgbaNormal, draw.background);

    // From scratch on the moved cage, with the same tiles (they depend on the topology only).
    const ControlMesh movedMesh(moved);
    const BaseSurface movedBase(movedMesh, isolated(isolation));
    const DisplacedSurface movedSurface(movedBase, s.tiles);
    const RenderedImage fresh = SurfaceRenderer(ctx, draw, movedSurface).render(1, 0);

    REQUIRE(coveredPixels(fresh) > fresh.normals.size() / 20);
    CHECK(after.rgba == fresh.rgba);
    CHECK(sameBits(after.normals, fresh.normals));
    CHECK(after.depth == fresh.depth);
    CHECK(engineAfter.color == fresh.rgba);
    CHECK(sameBits(engineAfter.normals, fresh.normals));
    CHECK(after.rgba != before.rgba);
    CHECK(animated.uploadedBytes() == uploaded); // nothing re-uploaded at creation size
    // Moving back restores the first image.
    s.base.setControlPoints(s.mesh.description().positions);
    animated.updateControlPoints();
    CHECK(animated.render(1, 0).rgba == before.rgba);
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("engine: edited tiles through updateTiles render what a renderer of the edited tiles renders", "[engine]") {
    // Paper §5: after an edit only the modified tiles are re-fitted (TileFitter::refit) and
    // uploaded (updateTiles writes their footprints of the packed texture, nothing else).
    Context& ctx = dmgpu::context();
    const ControlMesh mesh = builtin::defaultMesh();
    const BaseSurface base(mesh);
    TileFitter fitter(mesh, uniformTileSizes(mesh, 4), FunctionSource(builtin::defaultDisplacement));
    const DisplacedSurface surface(base, fitter.tiles()); // reads the fitter's tiles in place
    const SurfaceDraw draw = smallDraw();
    SurfaceRenderer edited(ctx, draw, surface);
    RendererOptions o;
    o.target = kRgbaNormal;
    SurfaceRenderer engine(ctx, draw, surface, nullptr, o);
    const RenderedImage before = edited.render(1, 0);
    const std::size_t uploaded = edited.uploadedBytes();

    // A bump on every face the camera sees well: faces 0..3.
    const auto bumped = [](int face, double u, double v) {
        const double r2 = (u - 0.5) * (u - 0.5) + (v - 0.5) * (v - 0.5);
        return builtin::defaultDisplacement(face, u, v) + (face < 4 ? 0.08 * std::exp(-12.0 * r2) : 0.0);
    };
    const std::vector<int> changed = fitter.refit({0, 1, 2, 3}, bumped);
    REQUIRE(!changed.empty());
    REQUIRE(changed.size() < std::size_t(fitter.tiles().tileCount()));
    edited.updateTiles(changed);
    engine.updateTiles(changed);
    const RenderedImage after = edited.render(1, 0);
    const EngineImage engineAfter = drawAsEngine(ctx, engine, kRgbaNormal, draw.background);

    const TileSet copy = fitter.tiles();
    const DisplacedSurface fresh(base, copy);
    const RenderedImage reference = SurfaceRenderer(ctx, draw, fresh).render(1, 0);
    REQUIRE(coveredPixels(reference) > reference.normals.size() / 20);
    CHECK(after.rgba == reference.rgba);
    CHECK(sameBits(after.normals, reference.normals));
    CHECK(after.depth == reference.depth);
    CHECK(engineAfter.color == reference.rgba);
    CHECK(after.rgba != before.rgba);
    CHECK(edited.uploadedBytes() == uploaded);
    CHECK_THROWS_WITH(edited.updateTiles({fitter.tiles().tileCount()}), Catch::Contains("out of range"));
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("engine: half texels and the image path render what the CPU's texels say, bit for bit", "[engine]") {
    // The GPU reads texels exactly whichever way they are stored (uintBitsToFloat, unpackHalf2x16,
    // texelFetch of R32F / R16F), so: the image path renders the buffer path's image bit for bit,
    // and half texels render what float texels of the half-rounded tiles render.
    Context& ctx = dmgpu::context();
    const ControlMesh mesh = builtin::defaultMesh();
    const BaseSurface base(mesh);
    const TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 4), FunctionSource(builtin::defaultDisplacement));
    TileSet halved = tiles;
    for (Tile& t : halved.tiles)
        for (float& c : t.coefficients) c = halfValue(halfBits(c));
    const DisplacedSurface surface(base, tiles), halfSurface(base, halved);
    const auto render = [&](const DisplacedSurface& surf, TexelFormat format, TexelPath path) {
        SurfaceDraw draw = smallDraw();
        draw.effects.texelFormat = format;
        draw.effects.texelPath = path;
        return SurfaceRenderer(ctx, draw, surf).render(1, 0);
    };
    const RenderedImage floatBuffer = render(surface, TexelFormat::Float, TexelPath::Buffer);
    const RenderedImage floatImage = render(surface, TexelFormat::Float, TexelPath::Image);
    const RenderedImage halfBuffer = render(surface, TexelFormat::Half, TexelPath::Buffer);
    const RenderedImage halfImage = render(surface, TexelFormat::Half, TexelPath::Image);
    const RenderedImage rounded = render(halfSurface, TexelFormat::Float, TexelPath::Buffer);
    REQUIRE(coveredPixels(floatBuffer) > floatBuffer.normals.size() / 20);
    CHECK(floatImage.rgba == floatBuffer.rgba);
    CHECK(floatImage.depth == floatBuffer.depth);
    CHECK(sameBits(floatImage.normals, floatBuffer.normals));
    CHECK(halfImage.rgba == halfBuffer.rgba);
    CHECK(halfImage.depth == halfBuffer.depth);
    CHECK(sameBits(halfImage.normals, halfBuffer.normals));
    CHECK(halfBuffer.rgba == rounded.rgba);
    CHECK(halfBuffer.depth == rounded.depth);
    CHECK(sameBits(halfBuffer.normals, rounded.normals));
    CHECK(halfBuffer.depth != floatBuffer.depth); // the rounding is there to see
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("engine: edits reach half texels and the image path", "[engine]") {
    // As the edit test above, for every texel format and path: updateTiles writes the edited
    // footprints (whole words of half texels; then the image's rectangles) and the frame equals
    // a fresh renderer's of the edited tiles.
    Context& ctx = dmgpu::context();
    const ControlMesh mesh = builtin::defaultMesh();
    const BaseSurface base(mesh);
    for (const TexelFormat format : {TexelFormat::Float, TexelFormat::Half})
        for (const TexelPath path : {TexelPath::Buffer, TexelPath::Image}) {
            INFO(toString(format) << " texels, " << toString(path));
            TileFitter fitter(mesh, uniformTileSizes(mesh, 4), FunctionSource(builtin::defaultDisplacement));
            const DisplacedSurface surface(base, fitter.tiles());
            SurfaceDraw draw = smallDraw();
            draw.effects.texelFormat = format;
            draw.effects.texelPath = path;
            SurfaceRenderer edited(ctx, draw, surface);
            const RenderedImage before = edited.render(1, 0);
            const auto bumped = [](int face, double u, double v) {
                const double r2 = (u - 0.5) * (u - 0.5) + (v - 0.5) * (v - 0.5);
                return builtin::defaultDisplacement(face, u, v) + (face < 4 ? 0.08 * std::exp(-12.0 * r2) : 0.0);
            };
            const std::vector<int> changed = fitter.refit({0, 1, 2, 3}, bumped);
            edited.updateTiles(changed);
            const RenderedImage after = edited.render(1, 0);
            const TileSet copy = fitter.tiles();
            const DisplacedSurface fresh(base, copy);
            const RenderedImage reference = SurfaceRenderer(ctx, draw, fresh).render(1, 0);
            CHECK(after.rgba == reference.rgba);
            CHECK(after.depth == reference.depth);
            CHECK(sameBits(after.normals, reference.normals));
            CHECK(after.rgba != before.rgba);
            // a coefficient beyond the half range: refused before anything is written
            if (format == TexelFormat::Half) {
                const std::vector<int> huge = fitter.refit({1}, [&](int face, double u, double v) { return face == 1 ? 1e5 : bumped(face, u, v); });
                CHECK_THROWS_WITH(edited.updateTiles(huge), Catch::Contains("beyond the half-float range"));
                CHECK(edited.render(1, 0).rgba == reference.rgba); // nothing was written
            }
        }
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("engine: every light of a draw is shaded (up to kMaxLights)", "[engine]") {
    Context& ctx = dmgpu::context();
    Surface s;
    SurfaceDraw four = smallDraw();
    four.lights.assign(4, Light{{0.0, 0.0, 1.0}, {0.05, 0.05, 0.05}});
    SurfaceDraw eight = four;
    for (int i = 0; i < 4; ++i) eight.lights.push_back(Light{{0.3 * i - 0.5, 1.0, 0.2}, {0.2, 0.1, 0.05}});
    const RenderedImage a = SurfaceRenderer(ctx, four, s.surface).render(1, 0);
    const RenderedImage b = SurfaceRenderer(ctx, eight, s.surface).render(1, 0);
    CHECK(a.rgba != b.rgba);   // the last four lights add light
    CHECK(a.depth == b.depth); // to the same geometry
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("engine: image size changes, and what the engine mode refuses", "[engine]") {
    Context& ctx = dmgpu::context();
    const Surface s;
    SurfaceDraw draw = smallDraw();
    SurfaceRenderer r(ctx, draw, s.surface);
    const RenderedImage first = r.render(1, 0);
    r.setImageSize(120, 64);
    const RenderedImage resized = r.render(1, 0);
    CHECK(resized.width == 120);
    CHECK(resized.height == 64);
    CHECK(r.width() == 120);
    SurfaceDraw wide = draw;
    wide.width = 120;
    wide.height = 64;
    CHECK(resized.rgba == SurfaceRenderer(ctx, wide, s.surface).render(1, 0).rgba);
    r.setImageSize(draw.width, draw.height);
    CHECK(r.render(1, 0).rgba == first.rgba);
    CHECK_THROWS_AS(r.setImageSize(0, 10), ArgumentError);
    CHECK_THROWS_AS(r.setImageSize(10, kMaxImageSize + 1), ArgumentError);
    CHECK_THROWS_WITH(r.setImageSize(-3, 10), Catch::Contains("image size"));

    RendererOptions o;
    o.target = kBgraOnly;
    SurfaceRenderer engine(ctx, draw, s.surface, nullptr, o);
    CHECK_THROWS_AS(engine.render(), ArgumentError);
    CHECK_THROWS_WITH(engine.render(), Catch::Contains("recordDraw"));
    CHECK_THROWS_AS(engine.setImageSize(kMaxImageSize + 1, 10), ArgumentError);
    RendererOptions badDepth;
    badDepth.target = TargetFormats{VK_FORMAT_B8G8R8A8_UNORM, VK_FORMAT_UNDEFINED, VK_FORMAT_R8G8B8A8_UNORM};
    CHECK_THROWS_WITH(SurfaceRenderer(ctx, draw, s.surface, nullptr, badDepth), Catch::Contains("not a depth format"));
    RendererOptions noColor;
    noColor.target = TargetFormats{VK_FORMAT_UNDEFINED, VK_FORMAT_UNDEFINED, VK_FORMAT_D32_SFLOAT};
    CHECK_THROWS_AS(SurfaceRenderer(ctx, draw, s.surface, nullptr, noColor), ArgumentError);
    RendererOptions capture = o;
    capture.captureCapacity = 10;
    CHECK_THROWS_WITH(SurfaceRenderer(ctx, draw, s.surface, nullptr, capture), Catch::Contains("capture"));
    // An engine target drawn at a new size: the viewport and the screen-space factors follow.
    engine.setImageSize(120, 64);
    RendererOptions rgbaNormal;
    rgbaNormal.target = kRgbaNormal;
    SurfaceRenderer engineNormal(ctx, draw, s.surface, nullptr, rgbaNormal);
    engineNormal.setImageSize(120, 64);
    CHECK(bgraToRgba(drawAsEngine(ctx, engine, kBgraOnly, draw.background).color) == resized.rgba);
    CHECK(drawAsEngine(ctx, engineNormal, kRgbaNormal, draw.background).color == resized.rgba);
    dmgpu::checkNoValidationMessages();
}
