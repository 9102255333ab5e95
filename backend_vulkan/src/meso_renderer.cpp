// MesoRenderer: the maps' buffers, a render pass with five colour targets (colour, hit,
// ray origin, ray direction, counts), the graphics pipeline of one technique (specialisation
// constants), frames with timestamps and the read-back.
#include "dispmap/vulkan/meso_renderer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>

#include "dispmap/vulkan/buffer.h"
#include "dispmap/vulkan/meso_maps.h"

// SPIR-V of shaders/meso/ (NoContraction on every float operation: backend_vulkan/tools/spirv_exact.cpp).
#include "meso_frag_spv.h"
#include "meso_vert_spv.h"

namespace dispmap::vulkan {

namespace {

struct GpuMesoParams { // shaders/meso/common.glsl
    glm::mat4 viewProj;
    glm::vec4 eye, light, voxelsPerUnit, plane, background;
    glm::ivec4 dims0, dims1, dims2;
    glm::vec4 tol;
};
static_assert(sizeof(GpuMesoParams) == 64 + 5 * 16 + 3 * 16 + 16);

constexpr std::uint32_t kTargets = 5;
const VkFormat kFormats[kTargets] = {VK_FORMAT_R8G8B8A8_UNORM, VK_FORMAT_R32G32B32A32_SFLOAT, VK_FORMAT_R32G32B32A32_SFLOAT,
                                     VK_FORMAT_R32G32B32A32_SFLOAT, VK_FORMAT_R32G32B32A32_UINT};
const std::size_t kTexelBytes[kTargets] = {4, 16, 16, 16, 16};

struct Target {
    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;
};

double median(std::vector<double> v) {
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void validate(const MesoMaps& maps, const MesoRenderOptions& o) {
    if (o.width < 1 || o.height < 1 || o.width > 4096 || o.height > 4096)
        throw ArgumentError("meso renderer: image size " + std::to_string(o.width) + " x " + std::to_string(o.height) +
                            " out of range [1, 4096]");
    if (o.frames < 1 || o.warmup < 0) throw ArgumentError("meso renderer: frames must be >= 1 and warm-up frames >= 0");
    const MesoTechnique& t = o.technique;
    if ((t.method == MesoMethod::DistanceMap || t.method == MesoMethod::Ddm) && t.iterations < 1)
        throw ArgumentError("meso renderer: the technique needs at least one iteration (" + std::to_string(t.iterations) + ")");
    if ((t.method == MesoMethod::Relief || t.method == MesoMethod::Pom) && t.linear < 1)
        throw ArgumentError("meso renderer: relief mapping / POM need at least one linear step");
    if (t.method == MesoMethod::Relief && t.binary < 0) throw ArgumentError("meso renderer: relief mapping needs binary >= 0");
    if (t.method == MesoMethod::Ddm && (t.exitRule < 0 || t.exitRule > 1)) throw ArgumentError("meso renderer: exit rule must be 0 or 1");
    if (!std::isfinite(t.eps)) throw ArgumentError("meso renderer: eps must be finite");
    if (!(o.tileSize > 0) || !(o.depth > 0) || !(o.planeHalfSize > 0) || o.quads < 1 || o.quads > 256 ||
        !std::isfinite(o.tileSize + o.depth + o.planeHalfSize))
        throw ArgumentError("meso renderer: tile size, depth and plane size must be finite and > 0, quads in 1..256");
    if (!(o.camera.eye.z > 0) || !std::isfinite(o.camera.eye.x + o.camera.eye.y + o.camera.eye.z))
        throw ArgumentError("meso renderer: the camera must be above the plane z = 0 (eye.z > 0)");
    if (!(o.camera.fovYDeg > 0 && o.camera.fovYDeg < 180)) throw ArgumentError("meso renderer: field of view must be in (0, 180) degrees");
    if (!(glm::length(o.lightDirection) > 0) || !std::isfinite(glm::length(o.lightDirection)))
        throw ArgumentError("meso renderer: the light direction must be finite and non-zero");
    if (o.shadows) {
        if (!maps.ddm.cones.shadow && !maps.ddm.cones.isotropic)
            throw ArgumentError("meso renderer: shadows need a DDM with shadow cones (build the maps with ConeSet::shadow = true), "
                                "these have " + maps.ddm.cones.name());
        if (!(o.lightDirection.z > 0)) throw ArgumentError("meso renderer: shadows need a light above the horizon (z > 0)");
        if (o.shadowIterations < 1) throw ArgumentError("meso renderer: shadow iterations must be >= 1");
    }
    (void)mesoGpuSize(maps); // sizes agree
}

} // namespace

glm::dvec3 mesoVoxelsPerUnit(const MesoMaps& maps, const MesoRenderOptions& o) {
    return {double(maps.field.width) / o.tileSize, double(maps.field.height) / o.tileSize, double(maps.field.layers) / o.depth};
}

glm::dmat4 mesoViewProjection(const MesoRenderOptions& o) {
    const double far = 4.0 * (glm::length(o.camera.eye - o.camera.target) + 2.0 * o.planeHalfSize);
    glm::dmat4 proj = glm::perspectiveRH_ZO(glm::radians(o.camera.fovYDeg), double(o.width) / double(o.height), 1e-3, far);
    proj[1][1] = -proj[1][1]; // Vulkan's y points down
    return proj * glm::lookAtRH(o.camera.eye, o.camera.target, o.camera.up);
}

struct MesoRenderer::Impl {
    Context& ctx;
    MesoRenderOptions options;
    MesoBuffers maps;
    std::unique_ptr<Buffer> params;
    std::array<Target, kTargets> targets{};
    std::array<std::unique_ptr<Buffer>, kTargets> readBack;
    VkRenderPass renderPass = VK_NULL_HANDLE;
    VkFramebuffer framebuffer = VK_NULL_HANDLE;
    VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
    VkPipelineLayout layout = VK_NULL_HANDLE;
    VkDescriptorPool pool = VK_NULL_HANDLE;
    VkDescriptorSet set = VK_NULL_HANDLE;
    VkPipeline pipeline = VK_NULL_HANDLE;
    VkQueryPool timestamps = VK_NULL_HANDLE;

    Impl(Context& c, const MesoMaps& m, const MesoRenderOptions& o) : ctx(c), options(o), maps(uploadMesoMaps(c, m)) {}
    ~Impl() { destroy(); }

    void destroy() noexcept {
        const Functions& fn = ctx.fn();
        const VkDevice d = ctx.device();
        fn.vkDeviceWaitIdle(d);
        if (timestamps) fn.vkDestroyQueryPool(d, timestamps, nullptr);
        if (pipeline) fn.vkDestroyPipeline(d, pipeline, nullptr);
        if (pool) fn.vkDestroyDescriptorPool(d, pool, nullptr);
        if (layout) fn.vkDestroyPipelineLayout(d, layout, nullptr);
        if (setLayout) fn.vkDestroyDescriptorSetLayout(d, setLayout, nullptr);
        if (framebuffer) fn.vkDestroyFramebuffer(d, framebuffer, nullptr);
        if (renderPass) fn.vkDestroyRenderPass(d, renderPass, nullptr);
        for (Target& t : targets) {
            if (t.view) fn.vkDestroyImageView(d, t.view, nullptr);
            if (t.image) fn.vkDestroyImage(d, t.image, nullptr);
            if (t.memory) fn.vkFreeMemory(d, t.memory, nullptr);
            t = {};
        }
        timestamps = VK_NULL_HANDLE;
        pipeline = VK_NULL_HANDLE;
        pool = VK_NULL_HANDLE;
        layout = VK_NULL_HANDLE;
        setLayout = VK_NULL_HANDLE;
        framebuffer = VK_NULL_HANDLE;
        renderPass = VK_NULL_HANDLE;
    }

    void writeParams(const MesoMaps& m) {
        const MesoGpuSize s = mesoGpuSize(m);
        const glm::dvec3 vpu = mesoVoxelsPerUnit(m, options);
        GpuMesoParams p{};
        p.viewProj = glm::mat4(mesoViewProjection(options));
        p.eye = glm::vec4(glm::vec3(options.camera.eye), 1.0f);
        p.light = glm::vec4(glm::vec3(glm::normalize(options.lightDirection)), float(options.ambient));
        p.voxelsPerUnit = glm::vec4(glm::vec3(vpu), float(options.checkerVoxels));
        p.plane = glm::vec4(float(options.planeHalfSize), float(options.quads), 0.0f, 0.0f);
        p.background = glm::vec4(glm::vec3(options.background), 1.0f);
        p.dims0 = glm::ivec4(s.width, s.height, s.layers, s.block);
        p.dims1 = glm::ivec4(s.gx, s.gy, s.gz, s.coneM);
        p.dims2 = glm::ivec4(s.coneN, 0, 0, 0);
        p.tol = glm::vec4(s.tol, float(options.shadowOffset), 0.0f, 0.0f);
        params = std::make_unique<Buffer>(ctx, sizeof p);
        params->upload(&p, sizeof p);
    }

    void createTargets() {
        const Functions& fn = ctx.fn();
        const auto w = static_cast<std::uint32_t>(options.width), h = static_cast<std::uint32_t>(options.height);
        std::array<VkAttachmentDescription, kTargets> att{};
        std::array<VkAttachmentReference, kTargets> refs{};
        std::array<VkImageView, kTargets> views{};
        for (std::uint32_t i = 0; i < kTargets; ++i) {
            Target& t = targets[i];
            VkImageCreateInfo info{};
            info.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
            info.imageType = VK_IMAGE_TYPE_2D;
            info.format = kFormats[i];
            info.extent = {w, h, 1};
            info.mipLevels = 1;
            info.arrayLayers = 1;
            info.samples = VK_SAMPLE_COUNT_1_BIT;
            info.tiling = VK_IMAGE_TILING_OPTIMAL;
            info.usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
            info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
            info.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
            DISPMAP_VK_CHECK(fn, vkCreateImage, ctx.device(), &info, nullptr, &t.image);
            VkMemoryRequirements needs{};
            fn.vkGetImageMemoryRequirements(ctx.device(), t.image, &needs);
            VkMemoryAllocateInfo alloc{};
            alloc.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
            alloc.allocationSize = needs.size;
            alloc.memoryTypeIndex = ctx.findMemoryType(needs.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
            DISPMAP_VK_CHECK(fn, vkAllocateMemory, ctx.device(), &alloc, nullptr, &t.memory);
            DISPMAP_VK_CHECK(fn, vkBindImageMemory, ctx.device(), t.image, t.memory, 0);
            VkImageViewCreateInfo view{};
            view.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
            view.image = t.image;
            view.viewType = VK_IMAGE_VIEW_TYPE_2D;
            view.format = kFormats[i];
            view.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
            DISPMAP_VK_CHECK(fn, vkCreateImageView, ctx.device(), &view, nullptr, &t.view);
            views[i] = t.view;
            att[i].format = kFormats[i];
            att[i].samples = VK_SAMPLE_COUNT_1_BIT;
            att[i].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
            att[i].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
            att[i].stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
            att[i].stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
            att[i].initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
            att[i].finalLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
            refs[i] = {i, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
            readBack[i] = std::make_unique<Buffer>(ctx, static_cast<VkDeviceSize>(w) * h * kTexelBytes[i]);
        }
        VkSubpassDescription sub{};
        sub.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
        sub.colorAttachmentCount = kTargets;
        sub.pColorAttachments = refs.data();
        VkSubpassDependency dep{};
        dep.srcSubpass = 0;
        dep.dstSubpass = VK_SUBPASS_EXTERNAL;
        dep.srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
        dep.dstStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT;
        dep.srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
        dep.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
        VkRenderPassCreateInfo rp{};
        rp.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO;
        rp.attachmentCount = kTargets;
        rp.pAttachments = att.data();
        rp.subpassCount = 1;
        rp.pSubpasses = &sub;
        rp.dependencyCount = 1;
        rp.pDependencies = &dep;
        DISPMAP_VK_CHECK(fn, vkCreateRenderPass, ctx.device(), &rp, nullptr, &renderPass);
        VkFramebufferCreateInfo fb{};
        fb.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO;
        fb.renderPass = renderPass;
        fb.attachmentCount = kTargets;
        fb.pAttachments = views.data();
        fb.width = w;
        fb.height = h;
        fb.layers = 1;
        DISPMAP_VK_CHECK(fn, vkCreateFramebuffer, ctx.device(), &fb, nullptr, &framebuffer);
    }

    void createDescriptors() {
        const Functions& fn = ctx.fn();
        constexpr std::uint32_t n = 6; // maps 0..4, params 5
        std::array<VkDescriptorSetLayoutBinding, n> b{};
        for (std::uint32_t i = 0; i < n; ++i)
            b[i] = {i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, nullptr};
        VkDescriptorSetLayoutCreateInfo li{};
        li.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
        li.bindingCount = n;
        li.pBindings = b.data();
        DISPMAP_VK_CHECK(fn, vkCreateDescriptorSetLayout, ctx.device(), &li, nullptr, &setLayout);
        VkPipelineLayoutCreateInfo pl{};
        pl.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
        pl.setLayoutCount = 1;
        pl.pSetLayouts = &setLayout;
        DISPMAP_VK_CHECK(fn, vkCreatePipelineLayout, ctx.device(), &pl, nullptr, &layout);
        const VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, n};
        VkDescriptorPoolCreateInfo pi{};
        pi.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
        pi.maxSets = 1;
        pi.poolSizeCount = 1;
        pi.pPoolSizes = &size;
        DISPMAP_VK_CHECK(fn, vkCreateDescriptorPool, ctx.device(), &pi, nullptr, &pool);
        VkDescriptorSetAllocateInfo ai{};
        ai.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
        ai.descriptorPool = pool;
        ai.descriptorSetCount = 1;
        ai.pSetLayouts = &setLayout;
        DISPMAP_VK_CHECK(fn, vkAllocateDescriptorSets, ctx.device(), &ai, &set);
        const auto mb = maps.all();
        std::array<VkDescriptorBufferInfo, n> infos{};
        std::array<VkWriteDescriptorSet, n> writes{};
        for (std::uint32_t i = 0; i < n; ++i) {
            infos[i] = {i < 5 ? mb[i]->handle() : params->handle(), 0, VK_WHOLE_SIZE};
            writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
            writes[i].dstSet = set;
            writes[i].dstBinding = i;
            writes[i].descriptorCount = 1;
            writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
            writes[i].pBufferInfo = &infos[i];
        }
        fn.vkUpdateDescriptorSets(ctx.device(), n, writes.data(), 0, nullptr);
    }

    void createPipeline() {
        const Functions& fn = ctx.fn();
        const MesoTechnique& t = options.technique;
        const float eps = static_cast<float>(t.eps);
        std::uint32_t epsBits;
        std::memcpy(&epsBits, &eps, sizeof epsBits);
        const std::uint32_t spec[9] = {static_cast<std::uint32_t>(t.method),
                                       static_cast<std::uint32_t>(t.iterations),
                                       epsBits,
                                       t.quadrics ? 1u : 0u,
                                       static_cast<std::uint32_t>(t.exitRule),
                                       static_cast<std::uint32_t>(t.linear),
                                       static_cast<std::uint32_t>(t.binary),
                                       options.shadows ? 1u : 0u,
                                       static_cast<std::uint32_t>(options.shadowIterations)};
        std::array<VkSpecializationMapEntry, 9> entries{};
        for (std::uint32_t i = 0; i < 9; ++i) entries[i] = {i, i * 4, 4};
        const VkSpecializationInfo si{9, entries.data(), sizeof spec, spec};
        const std::uint32_t* code[2] = {meso_vert_spv, meso_frag_spv};
        const std::size_t bytes[2] = {sizeof(meso_vert_spv), sizeof(meso_frag_spv)};
        const VkShaderStageFlagBits stages[2] = {VK_SHADER_STAGE_VERTEX_BIT, VK_SHADER_STAGE_FRAGMENT_BIT};
        std::array<VkShaderModule, 2> modules{};
        std::array<VkPipelineShaderStageCreateInfo, 2> infos{};
        try {
            for (std::size_t i = 0; i < 2; ++i) {
                VkShaderModuleCreateInfo mi{};
                mi.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
                mi.codeSize = bytes[i];
                mi.pCode = code[i];
                DISPMAP_VK_CHECK(fn, vkCreateShaderModule, ctx.device(), &mi, nullptr, &modules[i]);
                infos[i].sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
                infos[i].stage = stages[i];
                infos[i].module = modules[i];
                infos[i].pName = "main";
                infos[i].pSpecializationInfo = i == 1 ? &si : nullptr;
            }
            VkPipelineVertexInputStateCreateInfo vi{};
            vi.sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO;
            VkPipelineInputAssemblyStateCreateInfo ia{};
            ia.sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO;
            ia.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
            VkPipelineViewportStateCreateInfo vp{};
            vp.sType = VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO;
            vp.viewportCount = 1;
            vp.scissorCount = 1;
            VkPipelineRasterizationStateCreateInfo rs{};
            rs.sType = VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO;
            rs.polygonMode = VK_POLYGON_MODE_FILL;
            rs.cullMode = VK_CULL_MODE_NONE;
            rs.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
            rs.lineWidth = 1.0f;
            VkPipelineMultisampleStateCreateInfo ms{};
            ms.sType = VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO;
            ms.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
            std::array<VkPipelineColorBlendAttachmentState, kTargets> blend{};
            for (auto& b : blend)
                b.colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT | VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
            VkPipelineColorBlendStateCreateInfo cb{};
            cb.sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO;
            cb.attachmentCount = kTargets;
            cb.pAttachments = blend.data();
            const VkDynamicState dyn[2] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
            VkPipelineDynamicStateCreateInfo dy{};
            dy.sType = VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO;
            dy.dynamicStateCount = 2;
            dy.pDynamicStates = dyn;
            VkGraphicsPipelineCreateInfo gi{};
            gi.sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO;
            gi.stageCount = 2;
            gi.pStages = infos.data();
            gi.pVertexInputState = &vi;
            gi.pInputAssemblyState = &ia;
            gi.pViewportState = &vp;
            gi.pRasterizationState = &rs;
            gi.pMultisampleState = &ms;
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
        if (ctx.timestampsSupported()) {
            VkQueryPoolCreateInfo qi{};
            qi.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
            qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
            qi.queryCount = 2;
            DISPMAP_VK_CHECK(fn, vkCreateQueryPool, ctx.device(), &qi, nullptr, &timestamps);
        }
    }

    void record(VkCommandBuffer cmd, bool readBackNow) {
        const Functions& fn = ctx.fn();
        const auto w = static_cast<std::uint32_t>(options.width), h = static_cast<std::uint32_t>(options.height);
        if (timestamps) fn.vkCmdResetQueryPool(cmd, timestamps, 0, 2);
        if (timestamps) fn.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, timestamps, 0);
        std::array<VkClearValue, kTargets> clear{};
        const glm::vec3 bg(options.background);
        clear[0].color = {{bg.x, bg.y, bg.z, 1.0f}};
        clear[1].color = {{0.0f, 0.0f, 0.0f, -1.0f}};
        clear[2].color = {{0.0f, 0.0f, 0.0f, 0.0f}};
        clear[3].color = {{0.0f, 0.0f, 0.0f, 0.0f}};
        clear[4].color.uint32[0] = clear[4].color.uint32[1] = clear[4].color.uint32[2] = clear[4].color.uint32[3] = 0;
        VkRenderPassBeginInfo rb{};
        rb.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO;
        rb.renderPass = renderPass;
        rb.framebuffer = framebuffer;
        rb.renderArea = {{0, 0}, {w, h}};
        rb.clearValueCount = kTargets;
        rb.pClearValues = clear.data();
        fn.vkCmdBeginRenderPass(cmd, &rb, VK_SUBPASS_CONTENTS_INLINE);
        const VkViewport viewport{0.0f, 0.0f, float(w), float(h), 0.0f, 1.0f};
        const VkRect2D scissor{{0, 0}, {w, h}};
        fn.vkCmdSetViewport(cmd, 0, 1, &viewport);
        fn.vkCmdSetScissor(cmd, 0, 1, &scissor);
        fn.vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout, 0, 1, &set, 0, nullptr);
        fn.vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline);
        fn.vkCmdDraw(cmd, static_cast<std::uint32_t>(6 * options.quads * options.quads), 1, 0, 0);
        fn.vkCmdEndRenderPass(cmd);
        if (timestamps) fn.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, timestamps, 1);
        if (readBackNow) {
            VkBufferImageCopy region{};
            region.imageExtent = {w, h, 1};
            region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
            for (std::uint32_t i = 0; i < kTargets; ++i)
                fn.vkCmdCopyImageToBuffer(cmd, targets[i].image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, readBack[i]->handle(), 1, &region);
        }
        VkMemoryBarrier toHost{};
        toHost.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
        toHost.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
        toHost.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
        fn.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &toHost, 0, nullptr, 0, nullptr);
    }
};

MesoRenderer::MesoRenderer(Context& context, const MesoMaps& maps, const MesoRenderOptions& options) {
    validate(maps, options);
    impl_ = std::make_unique<Impl>(context, maps, options);
    impl_->writeParams(maps);
    impl_->createTargets();
    impl_->createDescriptors();
    impl_->createPipeline();
}

MesoRenderer::~MesoRenderer() = default;

MesoImage MesoRenderer::render() {
    Impl& m = *impl_;
    const Functions& fn = m.ctx.fn();
    std::vector<double> times;
    const int total = m.options.warmup + m.options.frames;
    for (int i = 0; i < total; ++i) {
        m.ctx.submitAndWait([&](VkCommandBuffer cmd) { m.record(cmd, i + 1 == total); });
        if (i >= m.options.warmup && m.timestamps) {
            std::uint64_t t[2] = {0, 0};
            DISPMAP_VK_CHECK(fn, vkGetQueryPoolResults, m.ctx.device(), m.timestamps, 0, 2, sizeof t, t, sizeof(std::uint64_t),
                             VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
            times.push_back(double(t[1] - t[0]) * m.ctx.timestampPeriodNs() * 1e-6);
        }
    }
    MesoImage out;
    out.width = m.options.width;
    out.height = m.options.height;
    out.gpuMs = median(times);
    out.frames = m.options.frames;
    const std::size_t pixels = static_cast<std::size_t>(out.width) * static_cast<std::size_t>(out.height);
    out.rgba.resize(pixels * 4);
    m.readBack[0]->download(out.rgba.data(), out.rgba.size());
    std::vector<glm::vec4> origin(pixels), dir(pixels);
    std::vector<glm::uvec4> counts(pixels);
    out.hitPoint.resize(pixels);
    m.readBack[1]->download(out.hitPoint.data(), pixels * sizeof(glm::vec4));
    m.readBack[2]->download(origin.data(), pixels * sizeof(glm::vec4));
    m.readBack[3]->download(dir.data(), pixels * sizeof(glm::vec4));
    m.readBack[4]->download(counts.data(), pixels * sizeof(glm::uvec4));
    out.iterations.resize(pixels);
    out.shadowIterations.resize(pixels);
    out.covered.resize(pixels);
    out.hit.resize(pixels);
    out.shadowed.resize(pixels);
    out.rayOrigin.resize(pixels);
    out.rayDir.resize(pixels);
    for (std::size_t i = 0; i < pixels; ++i) {
        out.covered[i] = origin[i].w > 0.5f ? 1 : 0;
        out.iterations[i] = counts[i].x;
        out.shadowIterations[i] = counts[i].y;
        out.shadowed[i] = counts[i].z ? 1 : 0;
        out.hit[i] = counts[i].w ? 1 : 0;
        out.rayOrigin[i] = glm::vec3(origin[i]);
        out.rayDir[i] = glm::vec3(dir[i]);
    }
    return out;
}

MesoImage renderMeso(Context& context, const MesoMaps& maps, const MesoRenderOptions& options) {
    MesoRenderer r(context, maps, options);
    return r.render();
}

} // namespace dispmap::vulkan
