#pragma once
// A dense triangle mesh (a scan or a sculpt): the target that baking casts rays at and measures
// distances to (bake/bake.h). It need not be manifold, closed or connected; it is only a cloud of
// triangles. What it must be is finite and not degenerate as a whole.
//
// Reading: OBJ through tinyobjloader (double precision, after surface/mesh.h's strict line
// check), PLY (ASCII and binary) and OFF through Open Asset Import Library (assimp), which keeps
// their indexed vertices. Polygons are fanned into triangles. Positions are stored as float:
// Embree's ray queries are single precision, and a 4M-vertex scan takes 48 MB, not 96.
//
// Rules (each a MeshError naming the file and the element, never a crash or a silent NaN):
//  * no triangle left, or all vertices at one point: an error;
//  * a NaN/Inf coordinate, or one beyond kMaxDenseCoordinate (squared distances must stay
//    finite in float): an error naming the vertex;
//  * a face index out of range: an error;
//  * vertices at one (float) position are merged (a triangle soup gets its connectivity back);
//  * a degenerate triangle (a repeated vertex or zero area in float) is dropped and counted
//    (scans have them; they are no target), as are vertices that no triangle uses.
#include <algorithm>
#include <array>
#include <cmath>
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include <assimp/DefaultLogger.hpp>
#include <assimp/Importer.hpp>
#include <assimp/LogStream.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <glm/glm.hpp>
#include <meshoptimizer.h>

#include "dispmap/core/error.h"
#include "dispmap/core/file_io.h"
#include "dispmap/surface/mesh.h"

namespace dispmap {

/// Coordinates beyond this are refused: squared distances of float coordinates must stay finite.
inline constexpr double kMaxDenseCoordinate = 1e18;
/// Dense meshes of more triangles are refused (indices are 32-bit; Embree's limit is higher).
inline constexpr std::uint64_t kMaxDenseTriangles = std::uint64_t{1} << 30;

struct DenseMeshStats {
    std::uint64_t polygons = 0;          ///< faces in the file
    std::uint64_t degenerateDropped = 0; ///< triangles with a repeated vertex or zero area, and faces of 1 or 2 vertices
    std::uint64_t unusedVertices = 0;    ///< vertices no kept triangle refers to (removed)
    std::uint64_t weldedVertices = 0;    ///< vertices at the position of an earlier one (merged into it)
};

struct DenseMesh {
    std::string name;
    std::vector<glm::vec3> positions;
    std::vector<glm::uvec3> triangles;
    DenseMeshStats stats;
    glm::dvec3 lo{0}, hi{0}; ///< bounding box

    /// Length of the bounding box's diagonal: the unit of every error figure of a bake.
    double diagonal() const { return glm::length(hi - lo); }
    int vertexCount() const { return static_cast<int>(positions.size()); }
    std::size_t triangleCount() const { return triangles.size(); }
};

/// Validates positions and triangles as the rules above say, drops degenerate triangles and
/// unused vertices, and sets the bounds. `name` is used in messages.
inline DenseMesh makeDenseMesh(std::string name, std::vector<glm::dvec3> positions,
                               const std::vector<std::array<std::uint64_t, 3>>& triangles, std::uint64_t polygons) {
    DenseMesh m;
    m.name = std::move(name);
    m.stats.polygons = polygons;
    if (triangles.empty()) throw MeshError(m.name + ": the mesh has no faces");
    if (triangles.size() > kMaxDenseTriangles)
        throw MeshError(m.name + ": " + std::to_string(triangles.size()) + " triangles are more than the " +
                        std::to_string(kMaxDenseTriangles) + " a dense mesh may have");
    const std::uint64_t nv = positions.size();
    for (std::size_t i = 0; i < positions.size(); ++i)
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(positions[i][c]) || std::abs(positions[i][c]) > kMaxDenseCoordinate)
                throw MeshError(m.name + ": vertex " + std::to_string(i + 1) + " has coordinate " +
                                std::to_string(positions[i][c]) +
                                (std::isfinite(positions[i][c]) ? " beyond the limit of 1e18" : ", not a finite number"));
    if (nv > kMaxDenseTriangles)
        throw MeshError(m.name + ": " + std::to_string(nv) + " vertices are more than the " + std::to_string(kMaxDenseTriangles) +
                        " a dense mesh may have");
    // Vertices at the same (float) position are one: a triangle soup (an STL converted to PLY,
    // a scan exported per face) gets its connectivity back, and its normals become smooth.
    std::vector<glm::vec3> fp(static_cast<std::size_t>(nv));
    for (std::size_t i = 0; i < fp.size(); ++i) fp[i] = glm::vec3(positions[i]);
    std::vector<unsigned> weld(fp.size());
    const std::size_t unique = fp.empty() ? 0 : meshopt_generateVertexRemap(weld.data(), nullptr, fp.size(), fp.data(), fp.size(), sizeof(glm::vec3));
    m.stats.weldedVertices = nv - unique;
    std::vector<glm::vec3> wpos(unique);
    for (std::size_t i = 0; i < fp.size(); ++i) wpos[weld[i]] = fp[i];
    std::vector<std::uint32_t> remap(unique, UINT32_MAX);
    m.triangles.reserve(triangles.size());
    std::uint32_t used = 0;
    for (std::size_t t = 0; t < triangles.size(); ++t) {
        const auto& raw = triangles[t];
        for (std::uint64_t v : raw)
            if (v >= nv)
                throw MeshError(m.name + ": triangle " + std::to_string(t + 1) + " refers to vertex " + std::to_string(v + 1) +
                                " of " + std::to_string(nv));
        const glm::uvec3 tri(weld[raw[0]], weld[raw[1]], weld[raw[2]]);
        const glm::vec3 a = wpos[tri.x], b = wpos[tri.y], c = wpos[tri.z];
        if (tri.x == tri.y || tri.y == tri.z || tri.x == tri.z || glm::length(glm::cross(b - a, c - a)) == 0.0f) {
            ++m.stats.degenerateDropped;
            continue;
        }
        glm::uvec3 out;
        for (int c2 = 0; c2 < 3; ++c2) {
            std::uint32_t& r = remap[tri[c2]];
            if (r == UINT32_MAX) r = used++;
            out[c2] = r;
        }
        m.triangles.push_back(out);
    }
    if (m.triangles.empty())
        throw MeshError(m.name + ": all " + std::to_string(triangles.size()) + " triangles are degenerate (zero area)");
    m.positions.resize(used);
    m.lo = glm::dvec3(std::numeric_limits<double>::infinity());
    m.hi = -m.lo;
    for (std::size_t v = 0; v < unique; ++v) {
        const std::uint32_t r = remap[v];
        if (r == UINT32_MAX) continue;
        m.positions[r] = wpos[v];
        m.lo = glm::min(m.lo, glm::dvec3(m.positions[r]));
        m.hi = glm::max(m.hi, glm::dvec3(m.positions[r]));
    }
    m.stats.unusedVertices = unique - used;
    if (!(m.diagonal() > 0.0)) throw MeshError(m.name + ": all vertices lie at one point");
    return m;
}

namespace detail {

/// Collects what assimp's loaders log as errors while one import runs: assimp repairs some
/// broken input (an OFF vertex index out of range) and only says so in its log. The logger is
/// global in assimp; imports through here are serialised, and an application's own logger (if
/// any) keeps running with this stream attached for the duration.
class AssimpErrors : public Assimp::LogStream {
  public:
    AssimpErrors() {
        lock_ = std::unique_lock<std::mutex>(mutex());
        created_ = Assimp::DefaultLogger::isNullLogger();
        if (created_) Assimp::DefaultLogger::create("", Assimp::Logger::NORMAL, 0);
        Assimp::DefaultLogger::get()->attachStream(this, Assimp::Logger::Err);
    }
    ~AssimpErrors() override {
        Assimp::DefaultLogger::get()->detachStream(this, Assimp::Logger::Err);
        if (created_) Assimp::DefaultLogger::kill();
    }
    AssimpErrors(const AssimpErrors&) = delete;
    AssimpErrors& operator=(const AssimpErrors&) = delete;
    void write(const char* message) override {
        if (first_.empty()) first_ = message;
        while (!first_.empty() && (first_.back() == '\n' || first_.back() == '\r')) first_.pop_back();
    }
    const std::string& first() const { return first_; }

  private:
    static std::mutex& mutex() {
        static std::mutex m;
        return m;
    }
    std::unique_lock<std::mutex> lock_;
    bool created_ = false;
    std::string first_;
};

/// Whether a PLY file holds less data than its header announces (assimp pads a short file with
/// zeros instead of failing): "" if it holds enough, else why not. Only the sizes are checked:
/// ASCII, one line per element at least; binary, every element's fixed-size properties, and
/// for lists their count and at least three entries.
inline std::string plyShortfall(const std::vector<unsigned char>& bytes) {
    const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
    const std::size_t end = text.find("end_header");
    if (end == std::string_view::npos) return ""; // not a header assimp reads either: its error speaks
    std::size_t body = text.find('\n', end);
    body = body == std::string_view::npos ? text.size() : body + 1;
    auto typeSize = [](std::string_view t) -> std::uint64_t {
        if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
        if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
        if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" || t == "float32") return 4;
        if (t == "double" || t == "float64") return 8;
        return 0;
    };
    bool ascii = false;
    std::uint64_t lines = 0, minBytes = 0, elements = 0;
    std::uint64_t count = 0;
    std::size_t pos = 0;
    while (pos < end) {
        std::size_t eol = text.find('\n', pos);
        if (eol == std::string_view::npos || eol > end) eol = end;
        std::string_view line = text.substr(pos, eol - pos);
        pos = eol + 1;
        std::vector<std::string_view> tok;
        for (std::size_t i = 0; i < line.size();) {
            while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
            std::size_t j = i;
            while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j]))) ++j;
            if (j > i) tok.push_back(line.substr(i, j - i));
            i = j;
        }
        if (tok.size() >= 2 && tok[0] == "format") ascii = tok[1] == "ascii";
        if (tok.size() >= 3 && tok[0] == "element") {
            count = std::strtoull(std::string(tok[2]).c_str(), nullptr, 10);
            // every element takes a byte at least: a larger count is a lie (and would overflow below)
            if (count > bytes.size())
                return "the header announces " + std::string(tok[2]) + " " + std::string(tok[1]) + " elements, more than a file of " +
                       std::to_string(bytes.size()) + " bytes can hold";
            lines += count;
            elements += count;
        }
        if (tok.size() >= 3 && tok[0] == "property") {
            if (tok[1] == "list" && tok.size() >= 5) minBytes += count * (typeSize(tok[2]) + 3 * typeSize(tok[3]));
            else minBytes += count * typeSize(tok[1]);
        }
    }
    if (ascii) {
        std::uint64_t have = 0;
        for (std::size_t i = body; i < text.size();) {
            std::size_t eol = text.find('\n', i);
            if (eol == std::string_view::npos) eol = text.size();
            if (text.substr(i, eol - i).find_first_not_of(" \t\r") != std::string_view::npos) ++have;
            i = eol + 1;
        }
        if (have < lines)
            return "the header announces " + std::to_string(lines) + " element lines, the file holds " + std::to_string(have) +
                   " (truncated?)";
    } else if (bytes.size() - body < minBytes) {
        return "the header announces " + std::to_string(elements) + " elements needing at least " + std::to_string(minBytes) +
               " bytes, the file holds " + std::to_string(bytes.size() - body) + " (truncated?)";
    }
    return "";
}

} // namespace detail

/// Reads a dense mesh from an OBJ, PLY or OFF file (by extension, case-insensitive). Throws
/// FileError for a file that cannot be read, MeshError for one that cannot be parsed or breaks
/// the rules above, ArgumentError for another extension.
inline DenseMesh readDenseMesh(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    std::vector<glm::dvec3> positions;
    std::vector<std::array<std::uint64_t, 3>> tris;
    std::uint64_t polygons = 0, pointsAndLines = 0;
    if (ext == ".obj") {
        TriangleSoup soup = readObjTriangles(path);
        for (const std::array<int, 3>& t : soup.triangles)
            tris.push_back({static_cast<std::uint64_t>(t[0]), static_cast<std::uint64_t>(t[1]), static_cast<std::uint64_t>(t[2])});
        polygons = soup.polygons;
        positions = std::move(soup.positions);
    } else if (ext == ".ply" || ext == ".off") {
        // The bytes go through our reader (regular files only, size capped) and then to assimp.
        const std::vector<unsigned char> bytes = detail::readFileBytes(path, "mesh file");
        if (ext == ".ply")
            if (const std::string why = detail::plyShortfall(bytes); !why.empty()) throw MeshError(path + ": " + why);
        Assimp::Importer importer;
        detail::AssimpErrors errors;
        // No post-processing: assimp's own steps would reorder or merge; our checks follow.
        const aiScene* scene = importer.ReadFileFromMemory(bytes.data(), bytes.size(), 0, ext.c_str() + 1);
        if (!scene) throw MeshError(path + ": cannot parse the " + ext.substr(1) + " file: " + importer.GetErrorString());
        if (!errors.first().empty()) throw MeshError(path + ": " + detail::excerpt(errors.first(), 120));
        for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
            const aiMesh* mesh = scene->mMeshes[mi];
            const std::uint64_t base = positions.size();
            for (unsigned i = 0; i < mesh->mNumVertices; ++i)
                positions.emplace_back(mesh->mVertices[i].x, mesh->mVertices[i].y, mesh->mVertices[i].z);
            for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
                const aiFace& face = mesh->mFaces[f];
                ++polygons;
                if (face.mNumIndices < 3) { // a point or a line (assimp's point clouds): no surface
                    ++pointsAndLines;
                    continue;
                }
                for (unsigned k = 1; k + 1 < face.mNumIndices; ++k)
                    tris.push_back({base + face.mIndices[0], base + face.mIndices[k], base + face.mIndices[k + 1]});
            }
        }
    } else {
        throw ArgumentError(path + ": unknown dense mesh format '" + ext + "' (OBJ, PLY or OFF)");
    }
    if (tris.empty() && pointsAndLines > 0)
        throw MeshError(path + ": the mesh has no faces, only " + std::to_string(pointsAndLines) + " points or lines (a point cloud?)");
    DenseMesh m = makeDenseMesh(path, std::move(positions), tris, polygons);
    m.stats.degenerateDropped += pointsAndLines;
    return m;
}

/// Area-weighted vertex normals (unit; a vertex whose triangles cancel gets (0, 0, 0)).
inline std::vector<glm::vec3> denseVertexNormals(const DenseMesh& m) {
    std::vector<glm::dvec3> acc(m.positions.size(), glm::dvec3(0.0));
    for (const glm::uvec3& t : m.triangles) {
        const glm::dvec3 a(m.positions[t.x]), b(m.positions[t.y]), c(m.positions[t.z]);
        const glm::dvec3 n = glm::cross(b - a, c - a);
        acc[t.x] += n;
        acc[t.y] += n;
        acc[t.z] += n;
    }
    std::vector<glm::vec3> out(acc.size(), glm::vec3(0.0f));
    for (std::size_t i = 0; i < acc.size(); ++i) {
        const double l = glm::length(acc[i]);
        if (l > 0.0) out[i] = glm::vec3(acc[i] / l);
    }
    return out;
}

} // namespace dispmap
