// The mesostructure marchers on the GPU (shaders/meso/march.glsl) against the CPU marchers
// (include/dispmap/meso/march.h): bit parity of hit, t and iteration count for every method on
// lavapipe; the MesoRenderer against the CPU marchers on its own pixel rays.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>

#include "gpu_support.h"
#include "meso_parity.h"

TEST_CASE("every mesostructure marcher agrees bit for bit between C++ and the compute shader", "[meso]") {
    auto& ctx = dmgpu::context();
    dispmap::parity::Options opt;
    opt.mesoRays = 2048; // 10 ray kinds x ~200; a few seconds under AddressSanitizer
    opt.filter = "march ";
    const bool strict = dispmap::parity::strictFor(ctx, opt);
    INFO("device " << ctx.deviceName() << (strict ? " (strict: no FMA contraction)" : ""));
    const auto results = dispmap::parity::runMeso(ctx, opt);
    REQUIRE(results.size() == 22);
    for (const auto& r : results) {
        INFO(r.kernel << ": " << r.bitExact << " of " << r.inputs << " bit-exact, max " << r.maxUlp << " ULP, worst " << r.worstInput);
        CHECK(r.inputs == 2048);
        CHECK(r.ok());
        // Lavapipe does not contract multiply-adds and rounds sqrt and division correctly
        // (measured): the GPU loop takes every decision the CPU takes.
        if (strict) CHECK(r.bitExact == r.inputs);
    }
    // The contract of other devices (the hit within 1/16 voxel for all but 0.1 % of the rays),
    // run here too so that its bookkeeping is tested where CI runs: on lavapipe no ray is over.
    opt.strict = 0;
    opt.filter = "march Ddm 4x1 quadrics";
    const auto loose = dispmap::parity::runMeso(ctx, opt);
    REQUIRE(loose.size() == 3);
    for (const auto& r : loose) {
        INFO(r.kernel << ": " << r.over << " over, worst " << r.worstInput);
        CHECK(r.allowedOver > 0);
        CHECK(r.bound == 1.0 / 16);
        CHECK(r.over == 0);
        CHECK(r.ok());
        if (strict) CHECK(r.maxUlp == 0);
    }
    // ok() in that mode counts the inputs over the bound, whatever the worst one.
    dispmap::parity::KernelResult k;
    k.inputs = 2000;
    k.bound = 1.0 / 16;
    k.allowedOver = 0.001;
    k.maxUlp = std::numeric_limits<double>::infinity();
    k.over = 2;
    CHECK(k.ok());
    k.over = 3;
    CHECK_FALSE(k.ok());
    dmgpu::checkNoValidationMessages();
}

// --- The renderer ---------------------------------------------------------------------------
#include "dispmap/kernels/meso_shade.h"
#include "dispmap/scene/meso.h"
#include "dispmap/vulkan/meso_renderer.h"

namespace {
// Four ULP of the 16-layer slab's top: how far a device whose division is not correctly rounded
// (Vulkan allows 2.5 ULP) may put a hit beyond the slab (see the curved-base test).
constexpr float kSlabUlps = 4.0f * 16.0f * std::numeric_limits<float>::epsilon();

// How far an 8-bit colour may be from 255 times the CPU's: lavapipe rounds a UNORM8 conversion
// to nearest (0.5, plus float noise); Vulkan lets other devices take either neighbour (1).
double unormTolerance(bool strict) { return strict ? 0.51 : 1.01; }

using dispmap::MesoMaps;
using dispmap::MesoMethod;
using dispmap::MesoTechnique;
using dispmap::vulkan::MesoImage;
using dispmap::vulkan::MesoRenderOptions;

const MesoMaps& shadowMaps() { // 4 x 1 view cones + shadow cones, the hard-case field
    static const MesoMaps maps = [] {
        dispmap::MesoMapOptions o;
        o.cones = dispmap::ConeSet{4, 1, true, false};
        return dispmap::buildMesoMaps(dispmap::parity::mesoParityField(16, 16, 16), o);
    }();
    return maps;
}

MesoRenderOptions smallScene(MesoMethod method) {
    // The parity rows and these scenes read every kind of compressed block: whole, one value,
    // and a plane (82 of the 512 grid words of these maps).
    REQUIRE(shadowMaps().ddm.planeBlocks() > 0);
    MesoRenderOptions o;
    o.width = 64;
    o.height = 48;
    o.frames = 1;
    o.warmup = 0;
    o.technique.method = method;
    o.technique.iterations = method == MesoMethod::Ddm ? 128 : 32;
    return o;
}

// The CPU marcher on the renderer's own per-pixel rays: same hit, t and iteration count.
struct RayParity {
    std::size_t covered = 0, same = 0;
};
RayParity rayParity(const MesoMaps& maps, const MesoTechnique& tq, const MesoImage& img) {
    RayParity p;
    for (std::size_t i = 0; i < img.covered.size(); ++i) {
        if (!img.covered[i]) continue;
        ++p.covered;
        if (!(img.rayDir[i].z < 0)) { // a curved base's back face: not marched (meso.frag)
            p.same += !img.hit[i] && img.iterations[i] == 0 ? 1u : 0u;
            continue;
        }
        const dispmap::MesoHit cpu = dispmap::marchMeso<float>(maps, tq, glm::dvec3(img.rayOrigin[i]), glm::dvec3(img.rayDir[i]));
        const auto t = static_cast<float>(cpu.t);
        const bool hitSame = cpu.hit == (img.hit[i] != 0) && cpu.iterations == static_cast<int>(img.iterations[i]);
        p.same += hitSame && (!cpu.hit || t == img.hitPoint[i].w) ? 1u : 0u;
    }
    return p;
}
} // namespace

TEST_CASE("the mesostructure renderer marches every pixel as the CPU marcher does", "[meso]") {
    auto& ctx = dmgpu::context();
    const bool strict = dmgpu::strict();
    for (const MesoMethod m : {MesoMethod::DistanceMap, MesoMethod::Ddm, MesoMethod::Relief, MesoMethod::Pom}) {
        MesoRenderOptions o = smallScene(m);
        const MesoImage img = dispmap::vulkan::renderMeso(ctx, shadowMaps(), o);
        INFO("method " << static_cast<int>(m));
        REQUIRE(img.rgba.size() == 64u * 48u * 4u);
        const RayParity p = rayParity(shadowMaps(), o.technique, img);
        CHECK(p.covered > 64u * 48u / 2); // the plane fills most of the view
        // The rays are the shader's own (read back), so on lavapipe every decision matches.
        if (strict) CHECK(p.same == p.covered);
        CHECK(std::isfinite(img.gpuMs));
    }
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("the renderer's pixel rays agree with camera rays computed on the CPU", "[meso]") {
    auto& ctx = dmgpu::context();
    MesoRenderOptions o = smallScene(MesoMethod::Ddm);
    const MesoImage img = dispmap::vulkan::renderMeso(ctx, shadowMaps(), o);
    const glm::dmat4 inv = glm::inverse(dispmap::vulkan::mesoViewProjection(o));
    const glm::dvec3 vpu = dispmap::vulkan::mesoVoxelsPerUnit(shadowMaps(), o);
    std::size_t both = 0, sameHit = 0, close = 0, hits = 0;
    for (int y = 0; y < o.height; ++y)
        for (int x = 0; x < o.width; ++x) {
            const std::size_t i = static_cast<std::size_t>(y * o.width + x);
            // The pixel centre's ray through the plane z = 0, in double.
            const glm::dvec2 ndc(2.0 * (x + 0.5) / o.width - 1.0, 2.0 * (y + 0.5) / o.height - 1.0);
            const glm::dvec4 far = inv * glm::dvec4(ndc, 1.0, 1.0);
            const glm::dvec3 dir = glm::dvec3(far) / far.w - o.camera.eye;
            if (!(dir.z < 0)) continue;
            const glm::dvec3 pos = o.camera.eye + dir * (-o.camera.eye.z / dir.z);
            if (std::abs(pos.x) > o.planeHalfSize || std::abs(pos.y) > o.planeHalfSize || !img.covered[i]) continue;
            ++both;
            const glm::vec3 ov = dispmap::kern::dmMesoEntry(glm::vec3(pos), glm::vec3(vpu), 16);
            const glm::vec3 dv = dispmap::kern::dmTangentToVoxel(glm::vec3(pos - o.camera.eye), glm::vec3(vpu));
            const dispmap::MesoHit cpu = dispmap::marchMeso<float>(shadowMaps(), o.technique, glm::dvec3(ov), glm::dvec3(dv));
            sameHit += cpu.hit == (img.hit[i] != 0) ? 1u : 0u;
            if (cpu.hit && img.hit[i]) {
                ++hits;
                const glm::dvec3 p = cpu.point(glm::dvec3(ov), glm::dvec3(dv));
                // The shader's world position is an interpolated varying, a few float ULP (~1e-6
                // voxels here) off the CPU's exact pixel-centre ray. Away from silhouettes (a wall
                // or the spike's edge, where the ray flips between two surfaces) the hit moves by
                // as much: 0.05 voxels is far above that and far below a voxel.
                close += glm::length(p - glm::dvec3(img.hitPoint[i])) < 0.05 ? 1u : 0u;
            }
        }
    INFO(both << " pixels, " << sameHit << " same hit/miss, " << close << " of " << hits << " hit points within 0.05 voxels");
    REQUIRE(both > 1000);
    CHECK(double(sameHit) >= 0.99 * double(both));
    CHECK(double(close) >= 0.97 * double(hits)); // silhouettes: a few per cent of the pixels at 64 x 48
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("shadows change only the pixels whose shadow ray the CPU finds blocked", "[meso]") {
    auto& ctx = dmgpu::context();
    const bool strict = dmgpu::strict();
    MesoRenderOptions o = smallScene(MesoMethod::Ddm);
    o.lightDirection = glm::dvec3(0.8, 0.2, 0.35); // low light: long shadows behind the wall and the spike
    const MesoImage off = dispmap::vulkan::renderMeso(ctx, shadowMaps(), o);
    o.shadows = true;
    const MesoImage on = dispmap::vulkan::renderMeso(ctx, shadowMaps(), o);
    const MesoMaps& maps = shadowMaps();
    const glm::vec3 vpu(dispmap::vulkan::mesoVoxelsPerUnit(maps, o));
    const glm::vec3 light(glm::normalize(o.lightDirection));
    std::size_t shadowed = 0, changed = 0, changedUnshadowed = 0, cpuSame = 0, hits = 0;
    for (std::size_t i = 0; i < on.covered.size(); ++i) {
        const bool diff = std::memcmp(&on.rgba[4 * i], &off.rgba[4 * i], 4) != 0;
        changed += diff ? 1u : 0u;
        changedUnshadowed += diff && !on.shadowed[i] ? 1u : 0u;
        shadowed += on.shadowed[i];
        CHECK(off.shadowed[i] == 0);
        CHECK(on.iterations[i] == off.iterations[i]); // the view march is the same pipeline code
        if (!on.hit[i]) continue;
        ++hits;
        // The shadow ray of meso.frag, on the CPU: from the hit point lifted along the normal.
        const glm::vec3 p(on.hitPoint[i]);
        glm::vec2 f;
        const glm::ivec2 c = dispmap::kern::dmHeightCell(glm::vec2(p.x, p.y), f);
        const glm::vec3 so = dispmap::kern::dmMesoShadowOrigin(p, maps.field.cell(c.x, c.y), f, static_cast<float>(o.shadowOffset));
        const glm::vec3 sd = dispmap::kern::dmTangentToVoxel(light, vpu);
        dispmap::DdmMarch opt;
        opt.maxIterations = o.shadowIterations;
        const dispmap::MesoHit s = dispmap::marchDdm<float>(dispmap::CompressedDdmView{&maps.ddm}, maps.ddm.cones, maps.field.layers,
                                                            &maps.quadrics, glm::dvec3(so), glm::dvec3(sd), opt);
        cpuSame += s.hit == (on.shadowed[i] != 0) && s.iterations == static_cast<int>(on.shadowIterations[i]) ? 1u : 0u;
    }
    INFO(hits << " hits, " << shadowed << " shadowed, " << changed << " changed, " << cpuSame << " shadow rays as on the CPU");
    CHECK(shadowed > 20);           // the scene has shadows to find
    CHECK(changedUnshadowed == 0);  // and they are the only change
    CHECK(changed > 0);
    if (strict) CHECK(cpuSame == hits);
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("the mesostructure renderer rejects bad input with clear errors", "[meso]") {
    auto& ctx = dmgpu::context();
    static const MesoMaps noShadow = [] {
        dispmap::MesoMapOptions o;
        o.cones = dispmap::ConeSet{4, 1, false, false};
        return dispmap::buildMesoMaps(dispmap::parity::mesoParityField(8, 8, 8), o);
    }();
    MesoRenderOptions o = smallScene(MesoMethod::Ddm);
    o.shadows = true;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, noShadow, o), Catch::Contains("shadow cones"));
    o = smallScene(MesoMethod::Ddm);
    o.width = 0;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), Catch::Contains("image size 0 x 48"));
    o = smallScene(MesoMethod::Ddm);
    o.camera.eye.z = -1;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), Catch::Contains("above the plane"));
    o = smallScene(MesoMethod::Relief);
    o.technique.linear = 0;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), Catch::Contains("1 to 1024 linear steps"));
    o.technique.linear = dispmap::kMaxMesoLinearSteps + 1; // a bent ray takes up to 4 times as many
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), Catch::Contains("1 to 1024 linear steps"));
    o = smallScene(MesoMethod::Ddm);
    o.frames = 0;
    CHECK_THROWS_AS(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), dispmap::ArgumentError);
    dmgpu::checkNoValidationMessages();
}

// --- Curved bases (FrameMesh) ---------------------------------------------------------------
#include "dispmap/surface/frame_mesh.h"
#include "dispmap/surface/tessellator.h"
#include "dispmap/surface/tile_builder.h"

namespace {
// The frame mesh of a control mesh's limit surface (zero tiles), tessellated uniformly.
std::shared_ptr<const dispmap::FrameMesh> frameMeshOf(const dispmap::ControlMesh& mesh, double factor, dispmap::FrameMeshOptions fo) {
    const dispmap::BaseSurface base(mesh);
    const dispmap::TileSet tiles =
        dispmap::buildTiles(mesh, dispmap::uniformTileSizes(mesh, 2), dispmap::FunctionSource([](int, double, double) { return 0.0; }));
    const dispmap::DisplacedSurface surface(base, tiles);
    const dispmap::TriangleMesh tess = dispmap::Tessellator(surface, dispmap::uniformTessFactors(base, factor)).tessellate();
    std::optional<dispmap::UvMap> uv;
    if (fo.placement == dispmap::FramePlacement::Uv) uv.emplace(mesh);
    return std::make_shared<const dispmap::FrameMesh>(dispmap::buildFrameMesh(surface, tess, uv ? &*uv : nullptr, fo));
}

const std::shared_ptr<const dispmap::FrameMesh>& spotBase() { // Spot by its UVs, four tiles a UV unit
    static const auto base = frameMeshOf(dispmap::ControlMesh::fromObjFile(std::string(DISPMAP_TEST_DATA) + "/spot_control_mesh.obj"), 3.0,
                                         {dispmap::FramePlacement::Uv, {4.0, 4.0}, dispmap::NormalMode::Accurate});
    return base;
}

MesoRenderOptions spotScene(MesoMethod method) {
    MesoRenderOptions o = smallScene(method);
    o.base = spotBase();
    o.camera.eye = {2.0, 0.9, -1.4};
    o.camera.target = {0.05, 0.12, 0.1};
    o.camera.up = {0.0, 1.0, 0.0};
    o.camera.fovYDeg = 40;
    o.depth = 0.05;
    o.lightDirection = {0.3, 0.8, -0.5};
    return o;
}
} // namespace

TEST_CASE("on a curved base the renderer marches every pixel as the CPU marcher does", "[meso]") {
    auto& ctx = dmgpu::context();
    const bool strict = dmgpu::strict();
    for (const MesoMethod m : {MesoMethod::DistanceMap, MesoMethod::Ddm, MesoMethod::Relief, MesoMethod::Pom}) {
        MesoRenderOptions o = spotScene(m);
        o.shadows = m == MesoMethod::Ddm;
        const MesoImage img = dispmap::vulkan::renderMeso(ctx, shadowMaps(), o);
        INFO("method " << static_cast<int>(m));
        const RayParity p = rayParity(shadowMaps(), o.technique, img);
        std::size_t hits = 0, backFaces = 0, frontMisses = 0;
        for (std::size_t i = 0; i < img.covered.size(); ++i) {
            if (!img.covered[i]) continue;
            hits += img.hit[i];
            // A pixel's ray is a unit voxel-space direction; one that does not go down is a back
            // face's, marched not at all (0 iterations, a miss).
            CHECK(std::abs(glm::length(img.rayDir[i]) - 1.0f) < 1e-5f);
            // No detail outside the shell: a hit lies in the slab below the base (voxel z in
            // [0, L]). Relief mapping's answer is its last bracket's midpoint: where the ray
            // meets the floor on a zero height, the linear search can step past it (the sample
            // on the floor rounds to just above it) and the bisections close in from below,
            // half a final bracket under the floor: 16 voxels / 32 steps / 2^6 / 2 = 1/256.
            // On a device whose division is not correctly rounded a floor hit o.z + t d.z may
            // land an ULP or so off the floor (1 ULP of 16 measured on an NVIDIA H200): 4 ULP.
            if (img.hit[i]) {
                INFO("hit z " << img.hitPoint[i].z);
                const float slack = strict ? 0.0f : kSlabUlps;
                CHECK((img.hitPoint[i].z >= (m == MesoMethod::Relief ? -1.0f / 256.0f : -slack) && img.hitPoint[i].z <= 16.0f + slack));
            }
            if (!(img.rayDir[i].z < 0)) {
                ++backFaces;
                CHECK((img.iterations[i] == 0 && !img.hit[i]));
            } else if (!img.hit[i]) {
                ++frontMisses;
            }
        }
        INFO(p.covered << " covered, " << hits << " hits, " << backFaces << " back faces, " << frontMisses << " front-face misses");
        CHECK(hits > 64u * 48u / 5); // Spot fills about half of the view
        // No holes inside the outline: height-field rays that go down always end on the field or
        // the slab's floor (the locally planar model has no silhouettes of its own yet).
        CHECK(frontMisses == 0);
        if (strict) CHECK(p.same == p.covered);
    }
    dmgpu::checkNoValidationMessages();
}

namespace {
// A 4 x 4 grid on [-1, 1]^2 in z = 0 with UVs over [0, 1]^2: its limit surface is the plane
// with s = 2 x + 2 at four tiles a UV unit, the plane's tile of 0.5 shifted by two whole
// tiles; its frames are the plane's axes (pS, pT along x and y).
std::shared_ptr<const dispmap::FrameMesh> flatGridBase() {
    std::string obj;
    for (int j = 0; j <= 4; ++j)
        for (int i = 0; i <= 4; ++i)
            obj += "v " + std::to_string(-1.0 + 0.5 * i) + " " + std::to_string(-1.0 + 0.5 * j) + " 0\nvt " + std::to_string(0.25 * i) + " " +
                   std::to_string(0.25 * j) + "\n";
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
            const auto id = [](int a, int b) { return std::to_string(b * 5 + a + 1); };
            const std::string a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
            obj += "f " + a + "/" + a + " " + b + "/" + b + " " + c + "/" + c + " " + d + "/" + d + "\n";
        }
    // Corners interpolated as in the OBJ's boundary rule "edge and corner": the limit surface of
    // a flat grid is the grid's own square.
    return frameMeshOf(dispmap::ControlMesh::fromObjText(obj + "t interpolateboundary 1/0/0 1\n", "flat grid"), 4.0,
                       {dispmap::FramePlacement::Uv, {4.0, 4.0}, dispmap::NormalMode::Accurate});
}
} // namespace

TEST_CASE("a flat base mesh renders the plane's hits", "[meso]") {
    // The flat grid (flatGridBase) against the plane. The two routes to the voxel ray (world
    // space, and the interpolated frame) differ by float rounding, so the hits agree to a
    // small fraction of a voxel.
    const auto base = flatGridBase();
    auto& ctx = dmgpu::context();
    MesoRenderOptions plane = smallScene(MesoMethod::Ddm);
    MesoRenderOptions mesh = plane;
    mesh.base = base;
    const MesoImage a = dispmap::vulkan::renderMeso(ctx, shadowMaps(), plane);
    const MesoImage b = dispmap::vulkan::renderMeso(ctx, shadowMaps(), mesh);
    const float W = 16.0f;
    std::size_t both = 0, close = 0, sameHit = 0;
    for (std::size_t i = 0; i < a.covered.size(); ++i) {
        if (!a.covered[i] || !b.covered[i]) continue;
        ++both;
        sameHit += a.hit[i] == b.hit[i] ? 1u : 0u;
        if (!a.hit[i] || !b.hit[i]) continue;
        glm::vec3 d = glm::vec3(b.hitPoint[i]) - glm::vec3(a.hitPoint[i]);
        d.x -= W * std::round(d.x / W); // the shift by whole tiles
        d.y -= W * std::round(d.y / W);
        close += glm::length(d) < 0.05f ? 1u : 0u;
    }
    INFO(both << " pixels, " << sameHit << " same hit/miss, " << close << " hit points within 0.05 voxels");
    REQUIRE(both > 64u * 48u / 2);
    CHECK(double(sameHit) >= 0.99 * double(both));
    // Silhouettes (a wall or the spike's edge, where a ray flips between two surfaces) move by
    // more: a few per cent of the pixels at 64 x 48, as in the CPU camera-ray test above.
    CHECK(double(close) >= 0.97 * double(both));
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("bad base meshes are refused before anything is drawn", "[meso]") {
    auto& ctx = dmgpu::context();
    MesoRenderOptions o = smallScene(MesoMethod::Ddm);
    o.base = std::make_shared<const dispmap::FrameMesh>();
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), Catch::Contains("the base mesh has 0 corners"));
    auto bad = std::make_shared<dispmap::FrameMesh>(*spotBase());
    bad->corners[5].pT.y = std::nan("");
    o.base = bad;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), Catch::Contains("base mesh corner 5 has a value that is not finite"));
    bad = std::make_shared<dispmap::FrameMesh>(*spotBase());
    bad->corners[7].pT = bad->corners[7].pS * 2.0; // a singular frame
    o.base = bad;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), Catch::Contains("corner 7: its frame is singular"));
    bad = std::make_shared<dispmap::FrameMesh>(*spotBase());
    bad->corners[2].tex.x = 1e5; // 1.6e6 voxels: float would lose the texel
    o.base = bad;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), Catch::Contains("corner 2: texture coordinate beyond"));
    o.base = spotBase();
    o.checkerVoxels = -1;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), Catch::Contains("checker period"));
    // A base mesh needs no camera above z = 0 and no light above the plane's horizon.
    o = spotScene(MesoMethod::Ddm);
    o.camera.eye = {0.5, -2.0, -2.0};
    o.lightDirection = {0.0, 0.0, -1.0};
    o.shadows = true;
    CHECK_NOTHROW(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o));
    dmgpu::checkNoValidationMessages();
}

// --- The albedo (meso/albedo.h) -------------------------------------------------------------
namespace {
std::shared_ptr<const dispmap::MesoAlbedo> albedoOf(int w, int h, bool mips, bool checker, glm::vec2 shift = glm::vec2(0.0f)) {
    std::vector<std::uint8_t> px(4 * static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const std::size_t i = 4 * static_cast<std::size_t>(y * w + x);
            const bool on = ((x + y) & 1) != 0;
            px[i] = checker ? (on ? 255 : 0) : static_cast<std::uint8_t>(37 * x + 11 * y);
            px[i + 1] = checker ? px[i] : static_cast<std::uint8_t>(200 - 5 * y);
            px[i + 2] = checker ? px[i] : static_cast<std::uint8_t>(90 + 13 * x);
            px[i + 3] = 255;
        }
    return std::make_shared<const dispmap::MesoAlbedo>(dispmap::mesoAlbedo(w, h, px, mips, shift));
}
} // namespace

TEST_CASE("the albedo is the CPU's at every hit; its mips remove the aliasing", "[meso]") {
    auto& ctx = dmgpu::context();
    const bool strict = dmgpu::strict();
    for (const bool curved : {false, true})
    for (const glm::vec2 shift : {glm::vec2(0.0f), glm::vec2(1.5f, -0.75f)}) {
        // Unlit (ambient 1: the shade factor is exactly 1), one level: the colour is the
        // bilinear albedo at the hit, as the CPU samples it, to the 8-bit target's rounding;
        // read where the image's shift says (MesoAlbedo::shift) on both.
        MesoRenderOptions o = curved ? spotScene(MesoMethod::Ddm) : smallScene(MesoMethod::Ddm);
        o.ambient = 1.0;
        o.albedo = albedoOf(7, 5, false, false, shift);
        const MesoImage img = dispmap::vulkan::renderMeso(ctx, shadowMaps(), o);
        std::size_t hits = 0, close = 0;
        for (std::size_t i = 0; i < img.hit.size(); ++i) {
            if (!img.hit[i]) continue;
            ++hits;
            const glm::vec4 cpu = dispmap::sampleMesoAlbedo<float>(*o.albedo, glm::dvec2(img.hitPoint[i].x / 16.0f, img.hitPoint[i].y / 16.0f), 0.0);
            double worst = 0;
            for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(double(img.rgba[4 * i + static_cast<std::size_t>(c)]) - 255.0 * double(cpu[c])));
            close += worst <= unormTolerance(strict) ? 1u : 0u;
        }
        INFO((curved ? "Spot" : "plane") << ", shift (" << shift.x << ", " << shift.y << "): " << close << " of " << hits << " hit pixels within "
                                          << unormTolerance(strict) << " of the CPU's colour");
        REQUIRE(hits > 500);
        if (strict) CHECK(close == hits);
        CHECK(double(close) >= 0.99 * double(hits));
    }
    // A one-texel checker, several texels a pixel: without mips each pixel is one bilinear
    // sample of it, anything from black to white (aliasing; 0.029 measured), with them the
    // pixels average to grey (0.0015).
    const auto spread = [&](bool mips) {
        MesoRenderOptions o = smallScene(MesoMethod::Ddm);
        o.ambient = 1.0;
        o.albedo = albedoOf(64, 64, mips, true);
        const MesoImage img = dispmap::vulkan::renderMeso(ctx, shadowMaps(), o);
        double sum = 0, sum2 = 0, n = 0;
        for (std::size_t i = 0; i < img.hit.size(); ++i)
            if (img.hit[i]) {
                const double v = img.rgba[4 * i] / 255.0;
                sum += v;
                sum2 += v * v;
                n += 1;
            }
        return sum2 / n - (sum / n) * (sum / n);
    };
    const double without = spread(false), with = spread(true);
    INFO("variance of the grey level: " << without << " without mips, " << with << " with");
    CHECK(without > 0.01);
    CHECK(with < 0.2 * without);
    dmgpu::checkNoValidationMessages();
}

// --- The normal map (meso/albedo.h, kern::dmNormalMapTangent) -----------------------------------
TEST_CASE("the normal map shades every hit as the CPU reads it, on the plane and on a base", "[meso]") {
    auto& ctx = dmgpu::context();
    const bool strict = dmgpu::strict();
    // A 7 x 5 map of random heights (slopes up to about 1), one level: at each hit the shading
    // normal is the map's bilinear texel read at the hit, as the CPU reads it. With an albedo
    // too, the map's words start after the albedo's in the one image buffer.
    dispmap::HeightImage heights;
    heights.width = 7;
    heights.height = 5;
    std::mt19937 g(11);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (int i = 0; i < 35; ++i) heights.values.push_back(u(g));
    const auto map = std::make_shared<const dispmap::MesoAlbedo>(dispmap::mesoAlbedo(7, 5, dispmap::normalMapFromHeights(heights, 0.3), false));
    struct Case {
        bool grid;
        double scale;
        bool greenUp;
        bool albedo;
    };
    for (const Case c : {Case{false, 1.0, true, false}, Case{false, 0.5, false, false}, Case{false, 1.0, true, true}, Case{true, 1.0, true, false}}) {
        MesoRenderOptions o = smallScene(MesoMethod::Ddm);
        if (c.grid) o.base = flatGridBase();
        o.checkerVoxels = 0; // without an albedo image the plain colour (0.95, 0.85, 0.7)
        if (c.albedo) o.albedo = albedoOf(6, 4, false, false);
        o.normalMap = map;
        o.normalScale = c.scale;
        o.normalGreenUp = c.greenUp;
        const MesoImage img = dispmap::vulkan::renderMeso(ctx, shadowMaps(), o);
        const glm::vec3 light = glm::normalize(glm::vec3(o.lightDirection));
        const glm::vec3 plain(0.95f, 0.85f, 0.7f);
        std::size_t hits = 0, close = 0;
        for (std::size_t i = 0; i < img.hit.size(); ++i) {
            if (!img.hit[i]) continue;
            ++hits;
            // The plane's frame and the grid's are the axes: the tangent-space normal is the world's.
            const glm::vec3 n = dispmap::sampleMesoNormal<float>(*map, glm::dvec2(img.hitPoint[i].x / 16.0f, img.hitPoint[i].y / 16.0f), 0.0,
                                                                 c.scale, c.greenUp ? -1.0 : 1.0);
            const float shade = dispmap::kern::dmMesoShade<float>(1.0f, n, light, float(o.ambient), 1.0f);
            const glm::vec3 albedo =
                c.albedo ? glm::vec3(dispmap::sampleMesoAlbedo<float>(*o.albedo, glm::dvec2(img.hitPoint[i].x / 16.0f, img.hitPoint[i].y / 16.0f), 0.0))
                         : plain;
            double worst = 0;
            for (int k = 0; k < 3; ++k)
                worst = std::max(worst, std::abs(double(img.rgba[4 * i + static_cast<std::size_t>(k)]) - 255.0 * double(albedo[k] * shade)));
            // unormTolerance; on the grid the frame's float rounding moves a colour by up to a level.
            close += worst <= unormTolerance(strict) + (c.grid ? 0.5 : 0.0) ? 1u : 0u;
        }
        INFO((c.grid ? "grid" : "plane") << ", scale " << c.scale << (c.greenUp ? ", green up" : ", green down") << (c.albedo ? ", with an albedo: " : ": ")
                                         << close << " of " << hits
                                         << " hit pixels match the CPU's colour");
        REQUIRE(hits > 500);
        if (strict && !c.grid) CHECK(close == hits);
        CHECK(double(close) >= 0.99 * double(hits));
    }
    // Bad normal maps are refused.
    MesoRenderOptions o = smallScene(MesoMethod::Ddm);
    auto broken = std::make_shared<dispmap::MesoAlbedo>(*map);
    broken->words.resize(20);
    o.normalMap = broken;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), Catch::Contains("the normal map's words do not hold its levels"));
    auto nanShift = std::make_shared<dispmap::MesoAlbedo>(*map);
    nanShift->words[static_cast<std::size_t>(1 + 4 * map->levels())] = 0x7fc00000u; // a NaN shift
    o.normalMap = nanShift;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), Catch::Contains("its shift is not finite"));
    o.normalMap = map;
    o.normalScale = std::nan("");
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), o), Catch::Contains("the normal map's scale must be finite"));
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("on Spot a normal map made from the heights shades as the height field does", "[meso]") {
    // The frame's orientation on a curved base: the map's x along pS, its y (green up) along
    // -pT's image direction, so that the map of the marched field's own heights gives about the
    // height field's shading, and the same map read with the other green convention does not.
    auto& ctx = dmgpu::context();
    const dispmap::MesoHeightField field = dispmap::mesoFunctionField("waves", 32, 16);
    const MesoMaps maps = dispmap::buildMesoMaps(field, dispmap::MesoMapOptions{});
    MesoRenderOptions o = spotScene(MesoMethod::Ddm);
    o.checkerVoxels = 0;
    // The map's slope needs a tile's world width: Spot's mean (as a scene's "normals": "height").
    const double tile = o.base->meanTileWidth();
    dispmap::HeightImage heights;
    heights.width = heights.height = 32;
    heights.values = field.h;
    const MesoImage plain = dispmap::vulkan::renderMeso(ctx, maps, o);
    o.normalMap = std::make_shared<const dispmap::MesoAlbedo>(
        dispmap::mesoAlbedo(32, 32, dispmap::normalMapFromHeights(heights, o.depth / (16.0 * tile)), false));
    const MesoImage mapped = dispmap::vulkan::renderMeso(ctx, maps, o);
    o.normalGreenUp = false;
    const MesoImage flipped = dispmap::vulkan::renderMeso(ctx, maps, o);
    double right = 0, wrong = 0, n = 0;
    for (std::size_t i = 0; i < plain.hit.size(); ++i) {
        if (!plain.hit[i] || !mapped.hit[i] || !flipped.hit[i]) continue;
        n += 1;
        for (std::size_t k = 0; k < 3; ++k) {
            right += std::abs(double(mapped.rgba[4 * i + k]) - double(plain.rgba[4 * i + k]));
            wrong += std::abs(double(flipped.rgba[4 * i + k]) - double(plain.rgba[4 * i + k]));
        }
    }
    INFO(n << " hit pixels; mean colour difference to the height field's shading: " << right / (3 * n) << " levels with the map, "
           << wrong / (3 * n) << " with its green read the other way (tile " << tile << ")");
    REQUIRE(n > 500);
    CHECK(right < 0.5 * wrong);
    dmgpu::checkNoValidationMessages();
}

// --- Several mesostructures (MesoPart) ------------------------------------------------------
namespace {
// Spot's triangles in two groups by ptex face (even faces first: part 0), and a second
// mesostructure unlike the first: another field, isotropic cones, another size.
struct TwoParts {
    std::shared_ptr<const dispmap::FrameMesh> base;
    MesoMaps waves;
    std::vector<dispmap::vulkan::MesoPart> parts;
    MesoRenderOptions scene;
    TwoParts() {
        auto grouped = std::make_shared<dispmap::FrameMesh>(*spotBase());
        std::vector<int> groupOf(static_cast<std::size_t>(*std::max_element(grouped->faces.begin(), grouped->faces.end()) + 1));
        for (std::size_t f = 0; f < groupOf.size(); ++f) groupOf[f] = static_cast<int>(f % 2);
        const std::vector<int> counts = dispmap::groupFrameMesh(*grouped, groupOf, 2);
        base = grouped;
        MesoTechnique distance;
        distance.method = MesoMethod::DistanceMap;
        distance.iterations = 48;
        waves = dispmap::buildMesoMaps(dispmap::mesoFunctionField("waves", 32, 8),
                                       dispmap::mesoMapOptionsFor(distance, false, dispmap::ConeSet{0, 0, false, true}));
        scene = spotScene(MesoMethod::Ddm);
        scene.base = base;
        dispmap::vulkan::MesoPart a, b;
        a.maps = &shadowMaps();
        a.look = scene;
        a.look.shadows = true;
        a.triangles = counts[0];
        b.maps = &waves;
        b.look.technique = distance;
        b.look.depth = 0.03;
        b.look.checkerVoxels = 4;
        b.triangles = counts[1];
        parts = {a, b};
    }
    // Part k alone: its triangles as the whole base, drawn by the one-mesostructure constructor.
    MesoRenderOptions alone(std::size_t k) const {
        auto mesh = std::make_shared<dispmap::FrameMesh>();
        const std::size_t first = k == 0 ? 0 : 3 * static_cast<std::size_t>(parts[0].triangles);
        mesh->corners.assign(base->corners.begin() + static_cast<std::ptrdiff_t>(first),
                             base->corners.begin() + static_cast<std::ptrdiff_t>(first + 3 * static_cast<std::size_t>(parts[k].triangles)));
        MesoRenderOptions o = scene;
        static_cast<dispmap::vulkan::MesoLook&>(o) = parts[k].look; // its depth: the far plane moves, not the rays
        o.base = mesh;
        return o;
    }
};
} // namespace

TEST_CASE("several mesostructures in one pass: each pixel as its part alone draws it", "[meso]") {
    auto& ctx = dmgpu::context();
    const bool strict = dmgpu::strict();
    const TwoParts t;
    const MesoImage both = dispmap::vulkan::renderMeso(ctx, t.parts, t.scene);
    std::size_t drawn[2] = {0, 0}, same = 0, hits = 0;
    const MesoImage alone[2] = {dispmap::vulkan::renderMeso(ctx, *t.parts[0].maps, t.alone(0)),
                                dispmap::vulkan::renderMeso(ctx, *t.parts[1].maps, t.alone(1))};
    for (std::size_t i = 0; i < both.covered.size(); ++i) {
        if (!both.covered[i]) continue;
        REQUIRE(both.part[i] < 2);
        const std::size_t k = both.part[i];
        ++drawn[k];
        if (!both.hit[i]) continue;
        // A hit is the nearest fragment of all; alone, its part's nearest is the same fragment:
        // the same ray, hit, iterations and colour, bit for bit (one pipeline, one fragment).
        ++hits;
        const MesoImage& a = alone[k];
        same += a.covered[i] && a.hit[i] && a.rayOrigin[i] == both.rayOrigin[i] && a.rayDir[i] == both.rayDir[i] &&
                        a.hitPoint[i] == both.hitPoint[i] && a.iterations[i] == both.iterations[i] &&
                        a.shadowIterations[i] == both.shadowIterations[i] &&
                        std::equal(a.rgba.begin() + static_cast<std::ptrdiff_t>(4 * i), a.rgba.begin() + static_cast<std::ptrdiff_t>(4 * i + 4),
                                   both.rgba.begin() + static_cast<std::ptrdiff_t>(4 * i))
                    ? 1u
                    : 0u;
    }
    INFO(drawn[0] << " pixels of part 0, " << drawn[1] << " of part 1, " << hits << " hits, " << same << " as the part alone");
    CHECK(drawn[0] > 200);
    CHECK(drawn[1] > 200);
    CHECK(same == hits);
    // And each part's pixels against the CPU marcher with that part's maps and technique.
    for (std::size_t k = 0; k < 2; ++k) {
        MesoImage mine = both;
        for (std::size_t i = 0; i < mine.covered.size(); ++i) mine.covered[i] = mine.covered[i] && mine.part[i] == k;
        const RayParity p = rayParity(*t.parts[k].maps, t.parts[k].look.technique, mine);
        INFO("part " << k << ": " << p.same << " of " << p.covered << " as the CPU marcher");
        if (strict) CHECK(p.same == p.covered);
    }
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("several mesostructures: bad parts are refused before anything is drawn", "[meso]") {
    auto& ctx = dmgpu::context();
    TwoParts t;
    using dispmap::vulkan::MesoRenderer;
    auto parts = t.parts;
    parts[1].triangles += 1;
    CHECK_THROWS_WITH(MesoRenderer(ctx, parts, t.scene), Catch::Contains("cover " + std::to_string(t.base->triangleCount() + 1) + " triangles"));
    parts = t.parts;
    parts[1].maps = nullptr;
    CHECK_THROWS_WITH(MesoRenderer(ctx, parts, t.scene), Catch::Contains("mesostructure 1 has no maps"));
    // Maps without what a part's look reads: the waves were built for the distance map alone.
    parts = t.parts;
    parts[1].look.shadows = true;
    CHECK_THROWS_WITH(MesoRenderer(ctx, parts, t.scene), Catch::Contains("mesostructure 1: the maps lack the DDM the technique or its shadows read"));
    parts = t.parts;
    parts[0].maps = &t.waves;
    CHECK_THROWS_WITH(MesoRenderer(ctx, parts, t.scene), Catch::Contains("mesostructure 0: the maps lack the DDM"));
    parts = t.parts;
    parts[1].look.technique.iterations = 0;
    CHECK_THROWS_WITH(MesoRenderer(ctx, parts, t.scene), Catch::Contains("mesostructure 1: the technique needs at least one iteration"));
    // A grouped base with other counts than its groups: refused, not drawn with the wrong maps.
    parts = t.parts;
    parts[0].triangles += 1;
    parts[1].triangles -= 1;
    CHECK_THROWS_WITH(MesoRenderer(ctx, parts, t.scene), Catch::Contains("the base mesh has 2 groups of triangles"));
    parts = {t.parts[0]};
    parts[0].triangles = t.base->triangleCount();
    CHECK_THROWS_WITH(MesoRenderer(ctx, parts, t.scene), Catch::Contains("the base mesh has 2 groups of triangles"));
    // An ungrouped base takes any split; a part of no triangles draws nothing.
    auto ungrouped = std::make_shared<dispmap::FrameMesh>(*t.base);
    ungrouped->groups.clear();
    MesoRenderOptions scene = t.scene;
    scene.base = ungrouped;
    parts = t.parts;
    parts[0].triangles = t.base->triangleCount();
    parts[1].triangles = 0;
    const MesoImage none = dispmap::vulkan::renderMeso(ctx, parts, scene);
    CHECK(std::count(none.part.begin(), none.part.end(), std::uint8_t{1}) == 0);
    CHECK(std::count(none.covered.begin(), none.covered.end(), std::uint8_t{1}) > 400);
    CHECK_THROWS_WITH(MesoRenderer(ctx, std::span<const dispmap::vulkan::MesoPart>{}, t.scene), Catch::Contains("0 mesostructures (1 .. 255)"));
    MesoRenderOptions plane = smallScene(MesoMethod::Ddm);
    CHECK_THROWS_WITH(MesoRenderer(ctx, t.parts, plane), Catch::Contains("several mesostructures need a base mesh"));
    // One part on the plane: its two triangles a quad.
    dispmap::vulkan::MesoPart one = t.parts[0];
    one.triangles = 2 * plane.quads * plane.quads;
    one.look.shadows = false;
    const MesoImage a = dispmap::vulkan::renderMeso(ctx, std::span<const dispmap::vulkan::MesoPart>(&one, 1), plane);
    static_cast<dispmap::vulkan::MesoLook&>(plane) = one.look;
    const MesoImage b = dispmap::vulkan::renderMeso(ctx, shadowMaps(), plane);
    CHECK(a.rgba == b.rgba);
    CHECK(a.iterations == b.iterations);
    dmgpu::checkNoValidationMessages();
}

// --- Non-height-field detail (meso/solid.h) -------------------------------------------------
namespace {
const MesoMaps& beadMaps() { // the parity runner's four beads, 4 x 1 view cones + shadow cones
    static const MesoMaps maps = [] {
        dispmap::MesoMapOptions o;
        o.cones = dispmap::ConeSet{4, 1, true, false};
        o.distance = false;
        return dispmap::buildMesoSolidMaps(dispmap::parity::mesoParitySolid(), o);
    }();
    return maps;
}
} // namespace

TEST_CASE("a solid renders as the CPU's solid march, with its shadows, on the plane and on Spot", "[meso][solid]") {
    auto& ctx = dmgpu::context();
    const bool strict = dmgpu::strict();
    const MesoMaps& maps = beadMaps();
    const std::vector<glm::uvec4> rows = dispmap::packSolid(maps.solid).triangles;
    for (const bool spot : {false, true}) {
        MesoRenderOptions o = spot ? spotScene(MesoMethod::Ddm) : smallScene(MesoMethod::Ddm);
        o.technique.iterations = 256;
        o.shadows = true;
        o.shadowIterations = 256;
        if (!spot) o.lightDirection = glm::dvec3(0.8, 0.2, 0.35); // low light: long shadows of the floating beads
        const MesoImage img = dispmap::vulkan::renderMeso(ctx, maps, o);
        INFO((spot ? "Spot" : "plane"));
        const RayParity p = rayParity(maps, o.technique, img);
        CHECK(p.covered > 64u * 48u / 4);
        if (strict) CHECK(p.same == p.covered);
        std::size_t hits = 0, beads = 0, shadowed = 0, shadowSame = 0, shaded = 0;
        const glm::vec3 vpu(dispmap::vulkan::mesoVoxelsPerUnit(maps, o));
        const glm::vec3 light(glm::normalize(o.lightDirection));
        for (std::size_t i = 0; i < img.covered.size(); ++i) {
            if (!img.covered[i] || !img.hit[i]) continue;
            ++hits;
            shadowed += img.shadowed[i];
            CHECK((img.hitPoint[i].z >= (strict ? 0.0f : -kSlabUlps) && img.hitPoint[i].z <= 16.0f + (strict ? 0.0f : kSlabUlps))); // inside the shell
            const dispmap::MesoSolidHit h = dispmap::marchDdmSolid<float>(dispmap::CompressedDdmView{&maps.ddm}, maps.ddm.cones, maps.solid,
                                                                          glm::dvec3(img.rayOrigin[i]), glm::dvec3(img.rayDir[i]), 256, 1);
            beads += h.triangle >= 0 ? 1u : 0u;
            if (spot) continue; // the frame of a Spot pixel is not read back: the plane checks the shadow rays
            // meso.frag's shadow ray on the CPU.
            // meso.frag's normals: the corners' mixed, turned with the face to the ray's side;
            // the shadow ray leaves along the face's own normal.
            glm::vec3 nv(0, 0, 1), gv(0, 0, 1);
            if (h.triangle >= 0) {
                const auto tri = static_cast<std::size_t>(h.triangle);
                nv = dispmap::kern::dmSolidCornerNormal(rows[3 * tri].w, rows[3 * tri + 1].w, rows[3 * tri + 2].w, glm::vec2(h.uv));
                gv = dispmap::kern::dmSolidFacing(glm::vec3(maps.solid.triangleRow(tri, 1)), glm::vec3(maps.solid.triangleRow(tri, 2)),
                                                  img.rayDir[i], nv);
            }
            const glm::vec3 so = glm::vec3(img.hitPoint[i]) + gv * static_cast<float>(o.shadowOffset);
            const glm::vec3 sd = dispmap::kern::dmTangentToVoxel(light, vpu);
            const dispmap::MesoSolidHit s = dispmap::marchDdmSolid<float>(dispmap::CompressedDdmView{&maps.ddm}, maps.ddm.cones, maps.solid,
                                                                          glm::dvec3(so), glm::dvec3(sd), o.shadowIterations, 1);
            shadowSame += s.hit == (img.shadowed[i] != 0) && s.iterations == static_cast<int>(img.shadowIterations[i]) ? 1u : 0u;
            // The pixel's red as the CPU shades it: the checker's albedo, Lambert with the corner
            // normals taken to the world (dmFrameVoxelNormal on the plane's axes); within one
            // level of 8 bits (the shader's float colour is rounded to UNORM8).
            const glm::vec3 n = dispmap::kern::dmFrameVoxelNormal(nv, glm::vec3(1, 0, 0), glm::vec3(0, 1, 0), glm::vec3(0, 0, 1), vpu);
            const float albedo = dispmap::kern::dmMesoChecker(glm::vec2(img.hitPoint[i]), static_cast<float>(o.checkerVoxels)) * 0.95f;
            const float red = albedo * dispmap::kern::dmMesoShade(1.0f, n, light, static_cast<float>(o.ambient), img.shadowed[i] ? 0.0f : 1.0f);
            shaded += std::abs(red * 255.0f - float(img.rgba[4 * i])) <= 1.0f ? 1u : 0u;
        }
        INFO(p.covered << " covered, " << hits << " hits, " << beads << " on a bead, " << shadowed << " shadowed, " << shadowSame
                       << " shadow rays as on the CPU, " << shaded << " shaded as on the CPU");
        CHECK(beads > hits / 5); // the beads are in view, not only the floor
        CHECK(shadowed > hits / 20);
        // Another device may pick another triangle at an edge (no bit parity): all of them on lavapipe.
        if (!spot && strict) CHECK(shaded == hits);
        if (!spot && strict) CHECK(shadowSame == hits);
        if (!spot) CHECK(shaded >= hits - hits / 50);
    }
    // What a solid cannot do: relief mapping / POM (they read heights), a normal map.
    MesoRenderOptions bad = smallScene(MesoMethod::Relief);
    CHECK_THROWS_WITH(dispmap::vulkan::renderMeso(ctx, maps, bad), Catch::Contains("marched by the DDM"));
    bad = smallScene(MesoMethod::Ddm);
    bad.normalMap = std::make_shared<const dispmap::MesoAlbedo>(dispmap::mesoAlbedo(2, 2, std::vector<std::uint8_t>(16, 128)));
    CHECK_THROWS_WITH(dispmap::vulkan::renderMeso(ctx, maps, bad), Catch::Contains("normal map needs a height field"));
    dmgpu::checkNoValidationMessages();
}

// --- Silhouettes (MesoRenderOptions::silhouettes, kern::dmShellExit) ---------------------------
namespace {
// A torus about the z axis (major radius kRm, tube radius kRt) with its exact frames and second
// fundamental form at every corner: phi around the axis, psi around the tube, ns x nt tiles.
constexpr double kRm = 1.0, kRt = 0.4;
std::shared_ptr<const dispmap::FrameMesh> torusBase(int ns, int nt, int segPhi, int segPsi) {
    const double tau = 6.283185307179586;
    auto corner = [&](int i, int j) {
        const double phi = tau * i / segPhi, psi = tau * j / segPsi;
        const double ring = kRm + kRt * std::cos(psi);
        dispmap::FrameVertex v;
        v.normal = {std::cos(psi) * std::cos(phi), std::cos(psi) * std::sin(phi), std::sin(psi)};
        v.position = glm::dvec3(ring * std::cos(phi), ring * std::sin(phi), kRt * std::sin(psi));
        v.tex = {double(ns) * i / segPhi, double(nt) * j / segPsi};
        const double a = tau / ns, b = tau / nt; // d phi / ds, d psi / dt
        v.pS = glm::dvec3(-std::sin(phi), std::cos(phi), 0.0) * (ring * a);
        v.pT = glm::dvec3(-std::sin(psi) * std::cos(phi), -std::sin(psi) * std::sin(phi), std::cos(psi)) * (kRt * b);
        // The most convex principal curvature: the tube's, -1 / kRt (the ring's is -cos(psi) / ring).
        v.shape = {-ring * std::cos(psi) * a * a, 0.0, -kRt * b * b, -1.0 / kRt};
        return v;
    };
    auto m = std::make_shared<dispmap::FrameMesh>();
    m->shaped = true;
    for (int i = 0; i < segPhi; ++i)
        for (int j = 0; j < segPsi; ++j)
            for (const auto& tri : {std::array<glm::ivec2, 3>{glm::ivec2(0, 0), glm::ivec2(1, 0), glm::ivec2(1, 1)},
                                    std::array<glm::ivec2, 3>{glm::ivec2(0, 0), glm::ivec2(1, 1), glm::ivec2(0, 1)}}) {
                std::array<dispmap::FrameVertex, 3> c;
                for (int k = 0; k < 3; ++k) c[static_cast<std::size_t>(k)] = corner(i + tri[static_cast<std::size_t>(k)].x, j + tri[static_cast<std::size_t>(k)].y);
                const glm::dvec2 shift = glm::floor(glm::min(glm::min(c[0].tex, c[1].tex), c[2].tex));
                for (auto& v : c) {
                    v.tex -= shift;
                    m->corners.push_back(v);
                }
                m->faces.push_back(0);
            }
    return m;
}

// How far a world point lies from the torus's core circle (the shell is [kRt - depth, kRt]).
double tubeDistance(const glm::dvec3& p) { return std::hypot(std::hypot(p.x, p.y) - kRm, p.z); }
} // namespace

TEST_CASE("silhouettes and bent rays: no detail drawn outside the curved shell, no holes inside the outline", "[meso][silhouette]") {
    // The hard-case field on an exact torus whose slab is a fifth of the tube's radius deep
    // (delta / R = 0.2: the locally planar march draws detail well outside the shell at the
    // outline). Each covered pixel's fragment is found again on the CPU (the triangles its
    // camera ray crosses, the one whose interpolated frame gives the GPU's voxel ray), its hit
    // taken to the world (dmFramePoint) and measured against the exact shell.
    auto& ctx = dmgpu::context();
    const bool strict = dmgpu::strict();
    const auto base = torusBase(24, 8, 96, 32);
    MesoRenderOptions o = smallScene(MesoMethod::Ddm);
    o.width = 96;
    o.height = 72;
    o.base = base;
    o.depth = 0.2 * kRt;
    o.camera.eye = {0.4, -2.6, 1.3};
    o.camera.target = {0.0, 0.0, 0.0};
    o.camera.up = {0.0, 0.0, 1.0};
    o.camera.fovYDeg = 50;
    o.shadows = true;
    o.lightDirection = {0.9, -0.2, 0.25}; // low: long shadows, and shadow rays that leave the curved top
    const glm::dmat4 inv = glm::inverse(dispmap::vulkan::mesoViewProjection(o));
    const int L = shadowMaps().field.layers;
    struct Count {
        std::size_t hits = 0, found = 0, outside = 0, cut = 0, coreRays = 0, holes = 0, deepHoles = 0, bentRays = 0, bentSame = 0, bent = 0, curved = 0;
        std::size_t cutFound = 0, overCut = 0, shadowSame = 0, shadowCut = 0;
        double worst = 0;
    };
    // maps: the hard-case field's (shadowMaps), or a solid's (no shadows then: the shadow rays
    // below are the height field's).
    auto measure = [&](bool silhouettes, bool bent, const MesoMaps& maps) {
        o.silhouettes = silhouettes;
        o.bentRays = bent;
        REQUIRE((maps.field.layers == L && !(maps.isSolid() && o.shadows)));
        const MesoImage img = dispmap::vulkan::renderMeso(ctx, maps, o);
        const glm::vec3 vpu(dispmap::vulkan::mesoVoxelsPerUnit(maps, o)); // (the depth's)
        Count c;
        // Bent rays: the CPU's bent march on each pixel's ray and bend, as the GPU marched it.
        for (std::size_t i = 0; i < img.covered.size() && bent; ++i) {
            if (!img.covered[i] || !(img.rayDir[i].z < 0)) continue;
            ++c.bentRays;
            glm::dvec3 slab;
            const dispmap::MesoHit h = dispmap::marchMesoBent<float>(maps, o.technique, glm::dvec3(img.rayOrigin[i]), glm::dvec3(img.rayDir[i]),
                                                                     dispmap::MesoBend(img.bend[i], img.curve[i]), &slab);
            // Lavapipe: hit, count, t and slab point bit for bit. Another device (sqrt and
            // division within Vulkan's few ULP, chords cut elsewhere): the same answer, t and the
            // slab point within 1/16 voxel (the parity rows' bound, meso_parity.cpp).
            const bool same = strict ? h.hit == (img.hit[i] != 0) && h.iterations == static_cast<int>(img.iterations[i]) &&
                                           (!h.hit || (float(h.t) == img.hitPoint[i].w && glm::vec3(slab) == glm::vec3(img.hitPoint[i])))
                                     : h.hit == (img.hit[i] != 0) &&
                                           (!h.hit || (std::abs(h.t - double(img.hitPoint[i].w)) <= 1.0 / 16 &&
                                                       glm::length(slab - glm::dvec3(img.hitPoint[i])) <= 1.0 / 16));
            c.bentSame += same ? 1u : 0u;
            c.bent += img.bend[i] != 0.0f ? 1u : 0u;
            c.curved += img.curve[i] < 0.0f ? 1u : 0u;
        }
        for (int y = 0; y < o.height; ++y)
            for (int x = 0; x < o.width; ++x) {
                const std::size_t i = static_cast<std::size_t>(y * o.width + x);
                const glm::dvec2 ndc(2.0 * (x + 0.5) / o.width - 1.0, 2.0 * (y + 0.5) / o.height - 1.0);
                const glm::dvec4 far = inv * glm::dvec4(ndc, 1.0, 1.0);
                const glm::dvec3 dir = glm::normalize(glm::dvec3(far) / far.w - o.camera.eye);
                // The pixel's ray against the floor's torus (tube kRt - depth), sphere-traced: a
                // ray that reaches it stays in the shell until the floor, so its pixel must hit.
                // Deep: it reaches a quarter of the depth below the floor (the locally quadric
                // shell's own error, as "outside" below), so that the bent march's floor, the
                // quadric's, lies on its path too.
                const auto reaches = [&](double tube) {
                    double t = 0;
                    for (int k = 0; k < 400 && t < 10; ++k) {
                        const double dist = tubeDistance(o.camera.eye + dir * t) - tube;
                        if (dist < 1e-7) break;
                        t += dist;
                    }
                    return t < 10;
                };
                if (reaches(kRt - o.depth)) {
                    ++c.coreRays;
                    c.holes += img.hit[i] ? 0u : 1u;
                    c.deepHoles += !img.hit[i] && reaches(kRt - 1.25 * o.depth) ? 1u : 0u;
                }
                c.cut += img.cut[i];
                if (!img.hit[i] && !img.cut[i]) continue;
                c.hits += img.hit[i];
                // The fragment: the crossed triangle whose frame gives the GPU's ray.
                for (std::size_t tri = 0; tri < base->corners.size(); tri += 3) {
                    const auto& A = base->corners[tri];
                    const auto& B = base->corners[tri + 1];
                    const auto& C = base->corners[tri + 2];
                    const glm::dvec3 e1 = B.position - A.position, e2 = C.position - A.position, pv = glm::cross(dir, e2);
                    const double det = glm::dot(e1, pv);
                    if (!(det != 0)) continue;
                    const glm::dvec3 tv = o.camera.eye - A.position;
                    const double u = glm::dot(tv, pv) / det;
                    const glm::dvec3 qv = glm::cross(tv, e1);
                    const double v = glm::dot(dir, qv) / det, tt = glm::dot(e2, qv) / det;
                    if (u < -1e-6 || v < -1e-6 || u + v > 1 + 1e-6 || tt <= 0) continue;
                    const double w0 = 1 - u - v;
                    const glm::dvec3 wp = o.camera.eye + dir * tt;
                    const glm::vec3 pS(w0 * A.pS + u * B.pS + v * C.pS), pT(w0 * A.pT + u * B.pT + v * C.pT);
                    glm::vec3 n(w0 * A.normal + u * B.normal + v * C.normal);
                    n = n * (1.0f / std::sqrt(glm::dot(n, n)));
                    const glm::vec2 tex(w0 * A.tex + u * B.tex + v * C.tex);
                    const glm::vec3 ov = dispmap::kern::dmMesoEntry(glm::vec3(tex, 0.0f), vpu, L);
                    const glm::vec3 dv = dispmap::kern::dmTangentToVoxel(dispmap::kern::dmFrameCoordinates(glm::vec3(wp - o.camera.eye), pS, pT, n), vpu);
                    if (glm::length(ov - img.rayOrigin[i]) > 0.05f || glm::length(dv - img.rayDir[i]) > 1e-3f) continue;
                    const glm::vec4 shape = dispmap::kern::dmShellLimit(glm::vec4(w0 * A.shape + u * B.shape + v * C.shape), vpu, float(L),
                                                                        float(dispmap::kShellCurvatureLimit));
                    if (img.cut[i]) {
                        // A cut pixel: its planar hit (the CPU's march on the GPU's ray) lies outside
                        // the exact shell, else the cut took away detail that is there.
                        ++c.cutFound;
                        const dispmap::MesoHit h = dispmap::marchMeso<float>(maps, o.technique, glm::dvec3(img.rayOrigin[i]),
                                                                             glm::dvec3(img.rayDir[i]));
                        const glm::vec3 q = img.rayOrigin[i] + img.rayDir[i] * float(h.t);
                        const double above = tubeDistance(glm::dvec3(dispmap::kern::dmFramePoint(glm::vec3(wp), q, ov, pS, pT, n, vpu))) - kRt;
                        c.overCut += !h.hit || above < -0.25 * o.depth ? 1u : 0u;
                        break;
                    }
                    ++c.found;
                    if (o.shadows) {
                        // The shadow ray of meso.frag on the CPU, from this fragment's frame, and
                        // the shell's exit that cuts it with silhouettes.
                        const glm::vec3 hp(img.hitPoint[i]);
                        glm::vec2 f;
                        const glm::ivec2 cc = dispmap::kern::dmHeightCell(glm::vec2(hp.x, hp.y), f);
                        const glm::vec3 so = dispmap::kern::dmMesoShadowOrigin(hp, shadowMaps().field.cell(cc.x, cc.y), f,
                                                                               static_cast<float>(o.shadowOffset));
                        const glm::vec3 sd = dispmap::kern::dmTangentToVoxel(
                            dispmap::kern::dmFrameCoordinates(glm::vec3(glm::normalize(o.lightDirection)), pS, pT, n), vpu);
                        bool shadowed = true;
                        if (sd.z > 0) {
                            dispmap::DdmMarch opt;
                            opt.maxIterations = o.shadowIterations;
                            const dispmap::MesoHit sh =
                                dispmap::marchDdm<float>(dispmap::CompressedDdmView{&shadowMaps().ddm}, shadowMaps().ddm.cones,
                                                         shadowMaps().field.layers, &shadowMaps().quadrics, glm::dvec3(so), glm::dvec3(sd), opt);
                            shadowed = sh.hit;
                            if (sh.hit && silhouettes) {
                                const glm::vec3 centre = bent ? glm::vec3(so.x, so.y, float(L)) : ov;
                                const float exitT = dispmap::kern::dmShellExit(so, sd, centre, shape, vpu, float(L));
                                if (exitT >= 0 && float(sh.t) > exitT) {
                                    shadowed = false;
                                    ++c.shadowCut;
                                }
                            }
                        }
                        c.shadowSame += shadowed == (img.shadowed[i] != 0) ? 1u : 0u;
                    }
                    // The world point is the straight ray's at the hit's t (with bent rays the
                    // slab point, hitPoint.xyz, is where the detail was read, not where it is).
                    const glm::vec3 p = img.rayOrigin[i] + img.rayDir[i] * img.hitPoint[i].w;
                    const glm::dvec3 world(dispmap::kern::dmFramePoint(glm::vec3(wp), p, ov, pS, pT, n, vpu));
                    const double above = tubeDistance(world) - kRt;
                    c.worst = std::max(c.worst, above);
                    // Outside: above the exact top by more than the model's own error allows: the
                    // quadric's neglected quartic term over the longest grazing path in the slab
                    // (about x^4 / (8 R^3) with x = sqrt(2 R delta): 0.1 delta), the flat triangles'
                    // sagitta (2e-3) and the interpolated frames: 0.25 delta.
                    c.outside += above > 0.25 * o.depth ? 1u : 0u;
                    break;
                }
            }
        INFO((bent ? "bent: " : silhouettes ? "silhouettes: " : "planar: ") << c.hits << " hits, " << c.found << " fragments found, " << c.outside
                                                          << " outside the shell (worst " << c.worst / o.depth << " delta above), " << c.cut
                                                          << " cut, " << c.holes << " holes of " << c.coreRays << " rays to the floor, "
                                                          << c.bentSame << " of " << c.bentRays << " rays as the CPU's bent march (" << c.bent << " bent), "
                                                          << c.overCut << " of " << c.cutFound << " cut pixels with their hit inside the shell, "
                                                          << c.shadowSame << " shadow rays as the CPU's (" << c.shadowCut << " cut)");
        // A pixel whose ray grazes a triangle edge may miss both on the CPU; on a device whose
        // rasteriser interpolates otherwise than lavapipe's, more (38 of 3270 on an NVIDIA H200).
        CHECK(c.found >= c.hits - c.hits / (strict ? 100 : 25));
        // A cut pixel is found when the CPU's exact barycentric frame gives the GPU's ray within
        // 1e-3: at the outline's grazing pixels the rasteriser's interpolation decides that,
        // and an NVIDIA H200's missed it for 25 of 80 (lavapipe's for under a tenth).
        CHECK(c.cutFound >= (strict ? c.cut - c.cut / 10 : c.cut / 2));
        // No cut hit lies well inside the shell: on the hard-case field. Where the floor shows
        // (the flat field below) the cut does take away floor the true ray reaches (counted).
        if (&maps == &shadowMaps()) CHECK(c.overCut == 0);
        // The CPU's frame is the exact barycentric one, the GPU's the rasteriser's float
        // interpolation: a shadow ray at a grazing edge may go the other way.
        if (o.shadows) CHECK(c.shadowSame >= c.found - c.found / 50);
        CHECK(c.coreRays > 1000);
        return c;
    };
    const Count planar = measure(false, false, shadowMaps()), cut = measure(true, false, shadowMaps()), bent = measure(false, true, shadowMaps()),
                bentCut = measure(true, true, shadowMaps());
    INFO("planar: " << planar.outside << " outside (worst " << planar.worst / o.depth << " delta), " << planar.holes << " holes; silhouettes: "
                    << cut.outside << " outside (worst " << cut.worst / o.depth << " delta), " << cut.cut << " cut, " << cut.holes
                    << " holes; bent: " << bent.outside << " outside (worst " << bent.worst / o.depth << " delta), " << bent.holes << " holes, "
                    << bent.bentSame << " of " << bent.bentRays << " as the CPU");
    // The planar march draws detail outside the shell at the outline; with silhouettes none.
    CHECK(planar.outside > 20); // 48 at 96 x 72 on lavapipe, up to 5.7 delta above the top
    CHECK(planar.cut == 0);
    CHECK(cut.cut > 20);
    CHECK(cut.outside == 0);
    CHECK(cut.shadowCut > 20); // shadow rays that leave the shell before they meet the detail
    // And no holes: every ray that reaches the floor's torus hits, with or without.
    CHECK(planar.holes == 0);
    CHECK(cut.holes == 0);
    // Bent rays leave the shell by themselves: nothing outside it, no holes, and every pixel's
    // ray marched as the CPU marches it (bit for bit on lavapipe: hit, t, slab point, count).
    CHECK(bent.outside == 0);
    CHECK(bent.holes == 0);
    // With silhouettes too, the shadow rays from the bent hits are cut where they leave the shell
    // (the quadric centred at the hit's column); the view rays are the same.
    CHECK(bentCut.shadowCut > 20);
    CHECK(bentCut.hits == bent.hits);
    CHECK(bentCut.outside == 0);
    CHECK(bent.bent > bent.bentRays / 2);
    CHECK(bent.curved > bent.bentRays / 2); // the tube is convex everywhere: the depth follows its curvature
    if (strict) CHECK(bent.bentSame == bent.bentRays);
    CHECK(bent.bentSame >= bent.bentRays - bent.bentRays / 50);
    // Relief mapping and POM along the same bent rays (kern::dmMesoMarchHeightBent, sampling the
    // bent ray itself): nothing outside the shell and every pixel as the CPU's march. Holes are
    // the linear search's own: a ray that grazes the convex shell dips into it for a short
    // stretch and comes back out, and steps as long as the straight ray's may step over where it
    // meets the detail (3 of 2586 rays to the floor on lavapipe, for both; none with 128
    // steps, which the relief pass with 128 checks). The DDM's conservative steps cannot step
    // over it. Donnelly's distance map (32 fixed steps along the bent ray,
    // kern::dmMesoMarchDistanceBent) as well (linear 0 below: its own iterations).
    for (const auto& [method, linear] : {std::pair{MesoMethod::Relief, 32}, std::pair{MesoMethod::Pom, 32}, std::pair{MesoMethod::Relief, 128},
                                         std::pair{MesoMethod::DistanceMap, 0}}) {
        o.technique = smallScene(method).technique;
        if (linear > 0) o.technique.linear = linear;
        const Count h = measure(false, true, shadowMaps());
        INFO((method == MesoMethod::Pom ? "POM" : method == MesoMethod::Relief ? "relief" : "distance map") << " " << linear << " bent: " << h.outside << " outside (worst " << h.worst / o.depth
                                                             << " delta), " << h.holes << " holes of " << h.coreRays << ", " << h.bentSame << " of "
                                                             << h.bentRays << " as the CPU");
        CHECK(h.outside == 0);
        CHECK(h.holes <= (linear >= 128 ? 0u : h.coreRays / 100));
        CHECK(h.bent > h.bentRays / 2);
        if (strict) CHECK(h.bentSame == h.bentRays);
        CHECK(h.bentSame >= h.bentRays - h.bentRays / 50);
    }
    // A solid (the parity runner's four beads) along the same bent rays: its chords marched with
    // the exact triangle tests (kern::dmMesoMarchDdmBent with `solid`), every pixel as the CPU's
    // march. The beads leave most of the floor in view, and there the locally quadric shell
    // decides (the hard-case field's walls stop the rays long before): rays that run a long way
    // along the torus's inner ring, through the saddle, find the quadric's floor where the true
    // one is not (a hole) or the other way round (a hit outside the shell). A flat field one
    // voxel high, marched by the height field's bent DDM on the same rays, measures that model
    // on its own; the solid may have no more holes than it, and at a slab a twentieth of the
    // radius deep nothing outside the shell and holes in under 1 % of the rays to the floor (8
    // of 3110 on lavapipe, as the flat field's).
    o.technique = smallScene(MesoMethod::Ddm).technique;
    o.technique.iterations = 256;
    o.shadows = false;
    dispmap::MesoMapOptions flatOptions;
    flatOptions.cones = dispmap::ConeSet{4, 1, true, false};
    const MesoMaps flat = dispmap::buildMesoMaps(dispmap::mesoHeightField(16, 16, 16, std::vector<float>(256, 0.0f)), flatOptions);
    for (const double depth : {0.2, 0.05}) {
        o.depth = depth * kRt;
        const Count floor = measure(false, true, flat), h = measure(false, true, beadMaps()), floorCut = measure(true, false, flat);
        INFO("solid bent, delta / R " << depth << ": " << h.hits << " hits, " << h.outside << " outside (worst " << h.worst / o.depth << " delta), "
                                      << h.holes << " holes of " << h.coreRays << " rays to the floor (" << h.deepHoles << " deep), "
                                      << h.bentSame << " of " << h.bentRays << " as the CPU; the flat field: " << floor.holes << " holes ("
                                      << floor.deepHoles << " deep), " << floor.outside << " outside");
        CHECK(h.hits > 1000);
        CHECK(h.bent > h.bentRays / 2);
        if (strict) CHECK(h.bentSame == h.bentRays);
        CHECK(h.bentSame >= h.bentRays - h.bentRays / 50);
        CHECK(h.holes <= floor.holes);
        if (depth < 0.1) {
            CHECK(h.outside == 0);
            CHECK(h.holes <= h.coreRays / 100);
        }
        WARN("bent rays on the torus, delta / R " << depth << ": the solid " << h.outside << " of " << h.hits << " hits outside the shell (worst "
                                                 << h.worst / o.depth << " delta above), " << h.holes << " holes of " << h.coreRays
                                                 << " rays to the floor (" << h.deepHoles << " reaching a quarter of the depth below it); a flat field "
                                                 << floor.outside << " of " << floor.hits << " outside, " << floor.holes << " holes of "
                                                 << floor.coreRays << " (" << floor.deepHoles << "); the flat field with silhouettes (planar) "
                                                 << floorCut.outside << " outside, " << floorCut.holes << " holes (" << floorCut.deepHoles << "), " << floorCut.overCut
                                                 << " cut hits well inside the shell");
    }
    o.depth = 0.2 * kRt;
    o.shadows = true;
    o.technique = smallScene(MesoMethod::Ddm).technique;
    // Without a base, or with one that carries no curvature, silhouettes are refused.
    MesoRenderOptions bad = smallScene(MesoMethod::Ddm);
    bad.silhouettes = true;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), bad), Catch::Contains("silhouettes need a curved base mesh"));
    bad.base = spotBase();
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), bad), Catch::Contains("FrameMeshOptions::shape"));
    auto wrongSign = std::make_shared<dispmap::FrameMesh>(*base);
    wrongSign->corners[4].shape.w = 0.5;
    bad.base = wrongSign;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), bad), Catch::Contains("corner 4: its most convex principal curvature"));
    bad.base = spotBase();
    bad.silhouettes = false;
    bad.bentRays = true;
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, shadowMaps(), bad), Catch::Contains("bent rays need the base mesh's curvature"));
    // Bent rays through the DDM need shadow cones: a ray bent back up marches up.
    bad = o;
    bad.bentRays = true;
    dispmap::MesoMapOptions viewOnly;
    viewOnly.cones = dispmap::ConeSet{4, 1, false, false};
    const MesoMaps noShadow = dispmap::buildMesoMaps(dispmap::parity::mesoParityField(16, 16, 16), viewOnly);
    CHECK_THROWS_WITH(dispmap::vulkan::MesoRenderer(ctx, noShadow, bad), Catch::Contains("needs shadow cones"));
    dmgpu::checkNoValidationMessages();
}
