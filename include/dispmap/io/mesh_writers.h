#pragma once
// Writers of a TriangleMesh (core/triangle_mesh.h): Wavefront OBJ and binary PLY, with texture
// coordinates, colours (PLY) and each vertex's Ptex (face, u, v) (PLY) if asked, each written
// atomically (core/file_io.h): a failed write leaves an existing file untouched. (glTF 2.0: the
// dispmap tool's examples/dispmap/gltf_export.h, which needs tinygltf.)
#include <bit>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/core/error.h"
#include "dispmap/core/file_io.h"
#include "dispmap/core/triangle_mesh.h"

namespace dispmap {

/// What writeObj and writePly write besides positions, normals and triangles. Every array is
/// per vertex: its size must be the mesh's vertex count.
struct MeshWriteOptions {
    /// RGB colours, PLY only (uchar red, green, blue).
    const std::vector<glm::u8vec3>* colours = nullptr;
    /// Texture coordinates (s, t) in the mesh's UV layout, origin at the bottom left (the OBJ and
    /// PLY convention; glTF's is the top left, see examples/dispmap/gltf_export.h). Finite, and
    /// for PLY within float range. OBJ `vt s t`, PLY float s, t.
    const std::vector<glm::dvec2>* texcoords = nullptr;
    /// PLY only: the Ptex face and parameters each vertex was evaluated at (TriangleMesh::faces,
    /// TriangleMesh::uvs) as int ptex_face, float ptex_u, float ptex_v.
    bool faceUV = false;
};

namespace detail {
inline void checkMeshForWriting(const TriangleMesh& m, const std::string& path) {
    if (m.normals.size() != m.positions.size())
        throw ArgumentError("cannot write '" + path + "': " + std::to_string(m.positions.size()) + " positions but " +
                            std::to_string(m.normals.size()) + " normals");
    for (const glm::ivec3& t : m.triangles)
        for (int i = 0; i < 3; ++i)
            if (t[i] < 0 || t[i] >= m.vertexCount())
                throw ArgumentError("cannot write '" + path + "': triangle refers to vertex " + std::to_string(t[i]) +
                                    " of " + std::to_string(m.vertexCount()));
}

// Throws ArgumentError unless a per-vertex array `what` has one entry per vertex.
inline void checkPerVertex(const TriangleMesh& m, const std::string& path, std::size_t size, const char* what) {
    if (size != m.positions.size())
        throw ArgumentError("cannot write '" + path + "': " + std::to_string(size) + " " + what + " for " +
                            std::to_string(m.positions.size()) + " vertices");
}

// Throws ArgumentError unless every (s, t) is finite (and, asFloat, within float range).
inline void checkTexcoords(const TriangleMesh& m, const std::string& path, std::span<const glm::dvec2> st, bool asFloat,
                           const char* what = "texture coordinates") {
    checkPerVertex(m, path, st.size(), what);
    constexpr double kFloatMax = std::numeric_limits<float>::max();
    for (std::size_t i = 0; i < st.size(); ++i)
        for (int c = 0; c < 2; ++c)
            if (!std::isfinite(st[i][c]) || (asFloat && std::abs(st[i][c]) > kFloatMax)) {
                std::string value;
                appendNumber(value, st[i][c]);
                throw ArgumentError("cannot write '" + path + "': " + what + " of vertex " + std::to_string(i) + " has " +
                                    value + (asFloat ? ", not a finite float" : ", not a finite number"));
            }
}
} // namespace detail

/// Writes `mesh` as Wavefront OBJ, atomically: `v x y z`, `vn x y z`, then, with
/// options.texcoords, `vt s t`, one of each per vertex; faces `f a//a b//b c//c`, or
/// `f a/a/a b/b/b c/c/c` with texcoords (1-based; vertex, texcoord and normal share the index).
/// Numbers are the shortest decimals that read back to the same double. Throws FileError naming
/// the path, ArgumentError (before anything is written) for a mesh whose arrays disagree, a
/// texcoord count that is not the vertex count, a non-finite texcoord, or options OBJ cannot
/// hold (colours, faceUV).
inline void writeObj(const TriangleMesh& mesh, const std::string& path, const MeshWriteOptions& options = {}) {
    detail::checkMeshForWriting(mesh, path);
    if (options.colours || options.faceUV)
        throw ArgumentError("cannot write '" + path + "': OBJ holds no vertex " +
                            (options.colours ? "colours" : "Ptex (face, u, v)") + " (write PLY)");
    const std::vector<glm::dvec2>* st = options.texcoords;
    if (st) detail::checkTexcoords(mesh, path, *st, false);
    std::string s = "# dispmap tessellation: " + std::to_string(mesh.vertexCount()) + " vertices, " +
                    std::to_string(mesh.triangleCount()) + " triangles\n";
    s.reserve(s.size() + mesh.positions.size() * (st ? 160 : 120) + mesh.triangles.size() * (st ? 60 : 40));
    for (const char* tag : {"v ", "vn "}) {
        const MeshArray<glm::dvec3>& a = tag[1] == 'n' ? mesh.normals : mesh.positions;
        for (const glm::dvec3& p : a) {
            s += tag;
            detail::appendNumber(s, p.x);
            s += ' ';
            detail::appendNumber(s, p.y);
            s += ' ';
            detail::appendNumber(s, p.z);
            s += '\n';
        }
    }
    if (st)
        for (const glm::dvec2& t : *st) {
            s += "vt ";
            detail::appendNumber(s, t.x);
            s += ' ';
            detail::appendNumber(s, t.y);
            s += '\n';
        }
    for (const glm::ivec3& t : mesh.triangles) {
        s += 'f';
        for (int i = 0; i < 3; ++i) {
            const std::string k = std::to_string(t[i] + 1);
            s += ' ';
            s += k;
            s += st ? "/" : "//";
            if (st) {
                s += k;
                s += '/';
            }
            s += k;
        }
        s += '\n';
    }
    detail::writeFileAtomically(path, std::vector<unsigned char>(s.begin(), s.end()), "OBJ mesh");
}

/// Writes `mesh` as binary little-endian PLY, atomically. Element vertex, each record in this
/// order:
///   float x, y, z, nx, ny, nz
///   float s, t                         with options.texcoords (texture coordinates)
///   uchar red, green, blue             with options.colours
///   int ptex_face, float ptex_u, ptex_v   with options.faceUV (TriangleMesh::faces and uvs)
/// then element face (list uchar uint vertex_indices). The texture coordinates are named s, t,
/// which Blender, MeshLab and assimp read as UVs; the Ptex parameters carry the ptex_ prefix
/// because some readers take a plain `u`, `v` for texture coordinates too. Throws as writeObj
/// (texcoords must also be within float range), and ArgumentError for a colour count, or with
/// faceUV a faces/uvs count, that is not the vertex count, or a non-finite Ptex parameter.
inline void writePly(const TriangleMesh& mesh, const std::string& path, const MeshWriteOptions& options = {}) {
    detail::checkMeshForWriting(mesh, path);
    const std::vector<glm::dvec2>* st = options.texcoords;
    const std::vector<glm::u8vec3>* colours = options.colours;
    if (st) detail::checkTexcoords(mesh, path, *st, true);
    if (colours) detail::checkPerVertex(mesh, path, colours->size(), "colours");
    if (options.faceUV) {
        detail::checkPerVertex(mesh, path, mesh.faces.size(), "Ptex faces");
        detail::checkTexcoords(mesh, path, mesh.uvs, true, "Ptex (u, v)");
    }
    const std::string header = "ply\nformat binary_little_endian 1.0\ncomment dispmap tessellation\nelement vertex " +
                               std::to_string(mesh.vertexCount()) +
                               "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty "
                               "float ny\nproperty float nz\n" +
                               (st ? "property float s\nproperty float t\n" : "") +
                               (colours ? "property uchar red\nproperty uchar green\nproperty uchar blue\n" : "") +
                               (options.faceUV ? "property int ptex_face\nproperty float ptex_u\nproperty float ptex_v\n" : "") +
                               "element face " + std::to_string(mesh.triangleCount()) +
                               "\nproperty list uchar uint vertex_indices\nend_header\n";
    const std::size_t record = std::size_t{24} + (st ? 8u : 0u) + (colours ? 3u : 0u) + (options.faceUV ? 12u : 0u);
    std::vector<unsigned char> bytes(header.begin(), header.end());
    bytes.reserve(bytes.size() + mesh.positions.size() * record + mesh.triangles.size() * 13);
    auto put32 = [&](std::uint32_t w) {
        for (int i = 0; i < 4; ++i) bytes.push_back(static_cast<unsigned char>(w >> (8 * i)));
    };
    auto putFloat = [&](double x) { put32(std::bit_cast<std::uint32_t>(static_cast<float>(x))); };
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
        const glm::dvec3 &p = mesh.positions[i], &n = mesh.normals[i];
        for (double x : {p.x, p.y, p.z, n.x, n.y, n.z}) putFloat(x);
        if (st) {
            putFloat((*st)[i].x);
            putFloat((*st)[i].y);
        }
        if (colours)
            for (int c = 0; c < 3; ++c) bytes.push_back((*colours)[i][c]);
        if (options.faceUV) {
            put32(static_cast<std::uint32_t>(mesh.faces[i]));
            putFloat(mesh.uvs[i].x);
            putFloat(mesh.uvs[i].y);
        }
    }
    for (const glm::ivec3& t : mesh.triangles) {
        bytes.push_back(3);
        for (int i = 0; i < 3; ++i) put32(static_cast<std::uint32_t>(t[i]));
    }
    detail::writeFileAtomically(path, bytes, "PLY mesh");
}

/// writePly with per-vertex colours only (the form before MeshWriteOptions; nullptr: none).
inline void writePly(const TriangleMesh& mesh, const std::string& path, const std::vector<glm::u8vec3>* colours) {
    MeshWriteOptions options;
    options.colours = colours;
    writePly(mesh, path, options);
}

} // namespace dispmap
