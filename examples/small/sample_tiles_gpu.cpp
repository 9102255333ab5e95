// Sample displacement tiles in your own GLSL compute shader (sample_tiles.comp) and compare
// with the same lookup on the CPU (PackedTiles::sampleD1): both run the kernels written once
// in include/dispmap/kernels/, so on lavapipe they agree bit for bit.
//
//   sample_tiles_gpu SAMPLE_TILES.spv
//
// Layers used: surface/ (to build tiles on a built-in mesh) and the Vulkan backend's compute
// helpers (Context, Buffer, ComputePipeline); any Vulkan code of your own works the same way.
#include <cstdio>
#include <fstream>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "dispmap/surface/builtin.h"
#include "dispmap/surface/tile_builder.h"
#include "dispmap/vulkan/buffer.h"
#include "dispmap/vulkan/compute.h"
#include "dispmap/vulkan/context.h"

namespace {
struct Query { // std430 layout of sample_tiles.comp's Query
    float u, v, rho;
    int record;
};
std::vector<std::uint32_t> readSpirv(const char* path) {
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    if (!in) throw dispmap::FileError(std::string("cannot open SPIR-V file '") + path + "'");
    std::vector<std::uint32_t> words(static_cast<std::size_t>(in.tellg()) / 4);
    in.seekg(0);
    in.read(reinterpret_cast<char*>(words.data()), static_cast<std::streamsize>(words.size() * 4));
    return words;
}
} // namespace

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: %s SAMPLE_TILES.spv\n", argv[0]);
        return 2;
    }
    try {
        const dispmap::ControlMesh mesh = dispmap::builtin::defaultMesh();
        const dispmap::TileSet tiles = dispmap::buildTiles(mesh, dispmap::uniformTileSizes(mesh, 4),
                                                           dispmap::FunctionSource(dispmap::builtin::defaultDisplacement));
        const dispmap::PackedTiles packed = tiles.pack();

        std::vector<Query> queries(4096);
        std::mt19937 rng(7);
        std::uniform_real_distribution<float> unit(0.0f, 1.0f), rho(0.0f, 6.0f);
        for (Query& q : queries)
            q = {unit(rng), unit(rng), rho(rng), static_cast<int>(rng() % packed.records.size())};
        std::vector<glm::uvec4> records;
        for (const dispmap::PatchRecord& r : packed.records) records.push_back(dispmap::recordWords(r));

        dispmap::vulkan::Context ctx; // lavapipe unless DISPMAP_VK_DEVICE names another device
        dispmap::vulkan::Buffer texels(ctx, packed.texels.size() * 4), recs(ctx, records.size() * 16),
            qs(ctx, queries.size() * sizeof(Query)), results(ctx, queries.size() * 16);
        texels.upload(packed.texels.data(), packed.texels.size() * 4);
        recs.upload(records.data(), records.size() * 16);
        qs.upload(queries.data(), queries.size() * sizeof(Query));
        const std::vector<std::uint32_t> spirv = readSpirv(argv[1]);
        const dispmap::vulkan::ComputePipeline pipeline(ctx, spirv, 4, 8);
        const struct {
            std::uint32_t count;
            std::int32_t width;
        } push{static_cast<std::uint32_t>(queries.size()), packed.width};
        const dispmap::vulkan::Buffer* bound[] = {&texels, &recs, &qs, &results};
        ctx.dispatch(pipeline, bound, glm::uvec3((queries.size() + 63) / 64, 1, 1), &push, sizeof push);

        std::size_t equal = 0;
        const std::span<const glm::vec4> gpu = results.as<const glm::vec4>();
        for (std::size_t i = 0; i < queries.size(); ++i) {
            const Query& q = queries[i];
            const glm::vec3 cpu = packed.sampleD1<float>(q.record, glm::vec2(q.u, q.v), q.rho);
            if (cpu == glm::vec3(gpu[i])) ++equal;
        }
        // With DISPMAP_VK_VALIDATION=1 the validation layer runs; any message is a failure.
        const std::vector<std::string> messages = ctx.takeValidationMessages();
        for (const std::string& m : messages) std::fprintf(stderr, "validation: %s\n", m.c_str());
        if (!messages.empty()) return 1;
        std::printf("%s: %zu of %zu lookups bit-identical to the CPU\n", ctx.deviceName().c_str(), equal, queries.size());
        return 0;
    } catch (const dispmap::Error& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
}
