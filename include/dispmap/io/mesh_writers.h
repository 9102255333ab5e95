#pragma once
// Writers of a TriangleMesh (core/triangle_mesh.h): Wavefront OBJ and binary PLY, each
// written atomically (core/file_io.h): a failed write leaves an existing file untouched.
#include <bit>
#include <charconv>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/core/error.h"
#include "dispmap/core/file_io.h"
#include "dispmap/core/triangle_mesh.h"

namespace dispmap {

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
} // namespace detail

/// Writes `mesh` as Wavefront OBJ (v, vn, f a//a b//b c//c; 1-based; shortest round-trip
/// decimal doubles), atomically. Throws FileError naming the path, ArgumentError for a mesh
/// whose arrays disagree.
inline void writeObj(const TriangleMesh& mesh, const std::string& path) {
    detail::checkMeshForWriting(mesh, path);
    std::string s = "# dispmap tessellation: " + std::to_string(mesh.vertexCount()) + " vertices, " +
                    std::to_string(mesh.triangleCount()) + " triangles\n";
    s.reserve(s.size() + mesh.positions.size() * 120 + mesh.triangles.size() * 40);
    for (const char* tag : {"v ", "vn "}) {
        const std::vector<glm::dvec3>& a = tag[1] == 'n' ? mesh.normals : mesh.positions;
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
    for (const glm::ivec3& t : mesh.triangles) {
        s += 'f';
        for (int i = 0; i < 3; ++i) {
            const std::string k = std::to_string(t[i] + 1);
            s += ' ';
            s += k;
            s += "//";
            s += k;
        }
        s += '\n';
    }
    detail::writeFileAtomically(path, std::vector<unsigned char>(s.begin(), s.end()), "OBJ mesh");
}

/// Writes `mesh` as binary little-endian PLY: element vertex (float x, y, z, nx, ny, nz, and
/// uchar red, green, blue when `colours` is given, one per vertex) and element face (list uchar
/// uint vertex_indices), atomically. Throws as writeObj, and ArgumentError for a colour count
/// that is not the vertex count.
inline void writePly(const TriangleMesh& mesh, const std::string& path, const std::vector<glm::u8vec3>* colours = nullptr) {
    detail::checkMeshForWriting(mesh, path);
    if (colours && colours->size() != mesh.positions.size())
        throw ArgumentError("cannot write '" + path + "': " + std::to_string(colours->size()) + " colours for " +
                            std::to_string(mesh.positions.size()) + " vertices");
    const std::string header = "ply\nformat binary_little_endian 1.0\ncomment dispmap tessellation\nelement vertex " +
                               std::to_string(mesh.vertexCount()) +
                               "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty "
                               "float ny\nproperty float nz\n" +
                               (colours ? "property uchar red\nproperty uchar green\nproperty uchar blue\n" : "") +
                               "element face " + std::to_string(mesh.triangleCount()) +
                               "\nproperty list uchar uint vertex_indices\nend_header\n";
    std::vector<unsigned char> bytes(header.begin(), header.end());
    bytes.reserve(bytes.size() + mesh.positions.size() * 24 + mesh.triangles.size() * 13);
    auto put32 = [&](std::uint32_t w) {
        for (int i = 0; i < 4; ++i) bytes.push_back(static_cast<unsigned char>(w >> (8 * i)));
    };
    auto putFloat = [&](double x) { put32(std::bit_cast<std::uint32_t>(static_cast<float>(x))); };
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
        const glm::dvec3 &p = mesh.positions[i], &n = mesh.normals[i];
        for (double x : {p.x, p.y, p.z, n.x, n.y, n.z}) putFloat(x);
        if (colours)
            for (int c = 0; c < 3; ++c) bytes.push_back((*colours)[i][c]);
    }
    for (const glm::ivec3& t : mesh.triangles) {
        bytes.push_back(3);
        for (int i = 0; i < 3; ++i) put32(static_cast<std::uint32_t>(t[i]));
    }
    detail::writeFileAtomically(path, bytes, "PLY mesh");
}

} // namespace dispmap
