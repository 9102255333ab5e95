// glTF 2.0 export of a TriangleMesh (gltf_export.h). tinygltf's implementation comes from
// Debian's libtinygltf (the TinyGLTF::TinyGLTF target), so this file includes only its
// declarations and needs neither stb nor nlohmann-json.
#include "gltf_export.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <tiny_gltf.h>

#include "dispmap/core/error.h"
#include "dispmap/core/file_io.h"
#include "dispmap/io/mesh_writers.h"

namespace dispmap {

namespace {

// The largest binary buffer written: GLB's lengths are 32-bit, and its JSON chunk (a few
// kilobytes here) and headers must fit beside the buffer. Applied to .gltf too, so either
// form converts to the other.
constexpr std::uint64_t kMaxBufferBytes = std::uint64_t{0xFFFFFFFF} - (std::uint64_t{1} << 20);

// glTF's buffers are little-endian, whatever the host.
void appendUint(std::vector<unsigned char>& b, std::uint32_t x) {
    for (int i = 0; i < 4; ++i) b.push_back(static_cast<unsigned char>(x >> (8 * i)));
}

void appendFloat(std::vector<unsigned char>& b, float x) { appendUint(b, std::bit_cast<std::uint32_t>(x)); }

// Adds a buffer view of the bytes [offset, end of buffer) and an accessor over all of it.
int addAccessor(tinygltf::Model& model, std::size_t offset, int target, int componentType, int type, std::size_t count) {
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = offset;
    view.byteLength = model.buffers[0].data.size() - offset;
    view.target = target;
    model.bufferViews.push_back(view);
    tinygltf::Accessor acc;
    acc.bufferView = static_cast<int>(model.bufferViews.size()) - 1;
    acc.byteOffset = 0;
    acc.componentType = componentType;
    acc.type = type;
    acc.count = count;
    model.accessors.push_back(acc);
    return static_cast<int>(model.accessors.size()) - 1;
}

} // namespace

void writeGltf(const TriangleMesh& mesh, const std::string& path, const std::vector<glm::dvec2>* texcoords) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); });
    const bool binary = ext == ".glb";
    if (!binary && ext != ".gltf")
        throw ArgumentError("cannot write '" + path + "': a glTF file must end in .glb (binary) or .gltf (JSON)");
    const auto fail = [&](const std::string& why) { return ArgumentError("cannot write '" + path + "': " + why); };
    detail::checkMeshForWriting(mesh, path);
    if (mesh.positions.empty() || mesh.triangles.empty())
        throw fail("an empty mesh (" + std::to_string(mesh.positions.size()) + " vertices, " +
                   std::to_string(mesh.triangles.size()) + " triangles) is not a valid glTF primitive");
    if (texcoords) detail::checkTexcoords(mesh, path, *texcoords, true);
    const std::uint64_t n = mesh.positions.size(), t = mesh.triangles.size();
    const std::uint64_t bytes = n * (24 + (texcoords ? 8 : 0)) + t * 12;
    if (n > 0xFFFFFFFFu || 3 * t > 0xFFFFFFFFu || bytes > kMaxBufferBytes)
        throw fail(std::to_string(n) + " vertices and " + std::to_string(t) + " triangles (" + std::to_string(bytes) +
                   " bytes) are more than a glTF binary buffer with uint32 indices holds");

    tinygltf::Model model;
    model.buffers.resize(1);
    std::vector<unsigned char>& b = model.buffers[0].data;
    b.reserve(static_cast<std::size_t>(bytes));

    std::vector<double> lo(3, std::numeric_limits<double>::infinity()), hi(3, -std::numeric_limits<double>::infinity());
    for (std::size_t i = 0; i < mesh.positions.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            const float x = static_cast<float>(mesh.positions[i][c]);
            if (!std::isfinite(x)) {
                std::string value;
                detail::appendNumber(value, mesh.positions[i][c]);
                throw fail("position of vertex " + std::to_string(i) + " has " + value + ", not a finite float");
            }
            appendFloat(b, x);
            const auto k = static_cast<std::size_t>(c);
            lo[k] = std::min(lo[k], static_cast<double>(x));
            hi[k] = std::max(hi[k], static_cast<double>(x));
        }
    const int position = addAccessor(model, 0, TINYGLTF_TARGET_ARRAY_BUFFER, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3,
                                     mesh.positions.size());
    model.accessors[static_cast<std::size_t>(position)].minValues = lo;
    model.accessors[static_cast<std::size_t>(position)].maxValues = hi;

    std::size_t offset = b.size();
    for (std::size_t i = 0; i < mesh.normals.size(); ++i) {
        const double len = glm::length(mesh.normals[i]);
        if (!(len > 0.0) || !std::isfinite(len))
            throw fail("normal of vertex " + std::to_string(i) + " has length " + std::to_string(len) + ": not a direction");
        const glm::dvec3 u = mesh.normals[i] / len;
        for (int c = 0; c < 3; ++c) appendFloat(b, static_cast<float>(u[c]));
    }
    const int normal = addAccessor(model, offset, TINYGLTF_TARGET_ARRAY_BUFFER, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                   TINYGLTF_TYPE_VEC3, mesh.normals.size());

    int texcoord = -1;
    if (texcoords) {
        offset = b.size();
        for (const glm::dvec2& st : *texcoords) {
            appendFloat(b, static_cast<float>(st.x));
            appendFloat(b, static_cast<float>(1.0 - st.y));
        }
        texcoord = addAccessor(model, offset, TINYGLTF_TARGET_ARRAY_BUFFER, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2,
                               texcoords->size());
    }

    offset = b.size();
    for (const glm::ivec3& tri : mesh.triangles)
        for (int c = 0; c < 3; ++c) appendUint(b, static_cast<std::uint32_t>(tri[c]));
    const int indices = addAccessor(model, offset, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                    TINYGLTF_TYPE_SCALAR, 3 * mesh.triangles.size());

    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    prim.attributes["POSITION"] = position;
    prim.attributes["NORMAL"] = normal;
    if (texcoord >= 0) prim.attributes["TEXCOORD_0"] = texcoord;
    prim.indices = indices;
    tinygltf::Mesh gmesh;
    gmesh.name = "dispmap tessellation";
    gmesh.primitives.push_back(prim);
    model.meshes.push_back(gmesh);
    tinygltf::Node node;
    node.mesh = 0;
    model.nodes.push_back(node);
    tinygltf::Scene scene;
    scene.nodes.push_back(0);
    model.scenes.push_back(scene);
    model.defaultScene = 0;
    model.asset.version = "2.0";
    model.asset.generator = "dispmap";

    std::ostringstream out(std::ios::out | std::ios::binary);
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToStream(&model, out, !binary, binary) || !out)
        throw FileError("cannot write glTF mesh '" + path + "': tinygltf could not serialise it");
    const std::string text = std::move(out).str();
    detail::writeFileAtomically(path, std::vector<unsigned char>(text.begin(), text.end()), "glTF mesh");
}

} // namespace dispmap
