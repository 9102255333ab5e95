#pragma once
// ControlMesh: a Catmull-Clark control mesh read from OBJ (OpenSubdiv's dialect: `t crease`,
// `t corner`, `t hole`, `t interpolateboundary`, `t creasemethod` tags), validated, and turned
// into OpenSubdiv's Far::TopologyRefiner and Far::PtexIndices. Topology questions are
// answered by OpenSubdiv; this file only carries the data in and checks it.
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>
#include <opensubdiv/far/ptexIndices.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>
#include <tiny_obj_loader.h>

#include "dispmap/core/error.h"
#include "dispmap/core/file_io.h"

namespace dispmap {
namespace Far = OpenSubdiv::Far;
namespace Sdc = OpenSubdiv::Sdc;

/// The raw description of a control mesh. Indices are 0-based.
struct MeshDescription {
    std::string name;                   ///< file name or label, used in error messages
    std::vector<glm::dvec3> positions;
    std::vector<int> faceSizes;         ///< vertices per face
    std::vector<int> faceVertices;      ///< concatenated, counter-clockwise
    std::vector<glm::dvec2> uvs;        ///< texture coordinates (may be empty)
    std::vector<int> faceUVs;           ///< per face-vertex index into uvs (empty or as faceVertices)
    std::vector<int> creaseVertexPairs; ///< two vertices per crease edge
    std::vector<float> creaseWeights;   ///< one per crease edge
    std::vector<int> cornerVertices;
    std::vector<float> cornerWeights;
    std::vector<int> holes;             ///< face indices
    Sdc::Options::VtxBoundaryInterpolation boundary = Sdc::Options::VTX_BOUNDARY_EDGE_ONLY;
    Sdc::Options::CreasingMethod creasing = Sdc::Options::CREASE_UNIFORM;
};


/// Parses OBJ text (OpenSubdiv's regression-shape dialect). Throws MeshError naming `name`.
inline MeshDescription parseObj(const std::string& text, const std::string& name) {
    tinyobj::ObjReaderConfig config;
    config.triangulate = false;
    config.vertex_color = false;
    config.mtl_search_path = "";
    tinyobj::ObjReader reader;
    if (!reader.ParseFromString(text, "", config) || !reader.Valid())
        throw MeshError(name + ": not a readable OBJ mesh: " + reader.Error());
    const tinyobj::attrib_t& attrib = reader.GetAttrib();
    MeshDescription d;
    d.name = name;
    if (attrib.vertices.size() % 3 != 0) throw MeshError(name + ": malformed vertex list");
    for (std::size_t i = 0; i + 2 < attrib.vertices.size(); i += 3)
        d.positions.emplace_back(attrib.vertices[i], attrib.vertices[i + 1], attrib.vertices[i + 2]);
    for (std::size_t i = 0; i + 1 < attrib.texcoords.size(); i += 2)
        d.uvs.emplace_back(attrib.texcoords[i], attrib.texcoords[i + 1]);
    bool anyUV = false, allUV = true;
    const std::vector<tinyobj::tag_t>* tags = nullptr;
    for (const tinyobj::shape_t& shape : reader.GetShapes()) {
        std::size_t at = 0;
        for (unsigned char n : shape.mesh.num_face_vertices) {
            d.faceSizes.push_back(n);
            for (unsigned char j = 0; j < n; ++j, ++at) {
                const tinyobj::index_t& ix = shape.mesh.indices[at];
                d.faceVertices.push_back(ix.vertex_index);
                d.faceUVs.push_back(ix.texcoord_index);
                if (ix.texcoord_index >= 0)
                    anyUV = true;
                else
                    allUV = false;
            }
        }
        // tinyobjloader accumulates tags and hands each shape the list so far.
        if (!tags || shape.mesh.tags.size() > tags->size()) tags = &shape.mesh.tags;
    }
    if (!anyUV || !allUV) {
        if (anyUV) throw MeshError(name + ": some faces have texture coordinates and some do not");
        d.faceUVs.clear();
        d.uvs.clear();
    }
    if (tags) {
        for (const tinyobj::tag_t& t : *tags) {
            auto bad = [&](const char* why) { return MeshError(name + ": tag '" + t.name + "': " + why); };
            if (t.name == "crease") {
                if (t.intValues.size() % 2 != 0 || t.floatValues.empty()) throw bad("needs vertex pairs and sharpness");
                const std::size_t n = t.intValues.size() / 2;
                if (t.floatValues.size() != 1 && t.floatValues.size() != n) throw bad("needs one sharpness or one per pair");
                for (std::size_t i = 0; i < n; ++i) {
                    d.creaseVertexPairs.push_back(t.intValues[2 * i]);
                    d.creaseVertexPairs.push_back(t.intValues[2 * i + 1]);
                    d.creaseWeights.push_back(static_cast<float>(t.floatValues[t.floatValues.size() == 1 ? 0 : i]));
                }
            } else if (t.name == "corner") {
                if (t.intValues.empty() || t.floatValues.empty()) throw bad("needs vertices and sharpness");
                if (t.floatValues.size() != 1 && t.floatValues.size() != t.intValues.size())
                    throw bad("needs one sharpness or one per vertex");
                for (std::size_t i = 0; i < t.intValues.size(); ++i) {
                    d.cornerVertices.push_back(t.intValues[i]);
                    d.cornerWeights.push_back(static_cast<float>(t.floatValues[t.floatValues.size() == 1 ? 0 : i]));
                }
            } else if (t.name == "hole") {
                d.holes.insert(d.holes.end(), t.intValues.begin(), t.intValues.end());
            } else if (t.name == "interpolateboundary") {
                if (t.intValues.size() != 1 || t.intValues[0] < 0 || t.intValues[0] > 2) throw bad("needs 0, 1 or 2");
                d.boundary = t.intValues[0] == 0   ? Sdc::Options::VTX_BOUNDARY_NONE
                             : t.intValues[0] == 1 ? Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER
                                                   : Sdc::Options::VTX_BOUNDARY_EDGE_ONLY;
            } else if (t.name == "creasemethod") {
                if (t.stringValues.size() != 1) throw bad("needs 'normal' or 'chaikin'");
                d.creasing = t.stringValues[0] == "chaikin" ? Sdc::Options::CREASE_CHAIKIN : Sdc::Options::CREASE_UNIFORM;
            }
            // Other tags (smoothtriangles, facevaryingpropagatecorners, ...) do not change
            // the Catmull-Clark limit surface of the vertex data; they are ignored.
        }
    }
    return d;
}

/// The polygons of an OBJ file fanned into triangles (vertex indices into `positions`): what a
/// voxeliser or a ray caster needs (meso/solid.h's mesoSolidFromMesh). FileError / MeshError
/// for a file that cannot be read or parsed.
struct TriangleSoup {
    std::vector<glm::dvec3> positions;
    std::vector<std::array<int, 3>> triangles;
};
inline TriangleSoup readObjTriangles(const std::string& path) {
    const std::vector<unsigned char> bytes = detail::readFileBytes(path, "mesh file");
    MeshDescription m = parseObj(std::string(bytes.begin(), bytes.end()), path);
    TriangleSoup out;
    std::size_t at = 0;
    for (int n : m.faceSizes) {
        for (int k = 1; k + 1 < n; ++k)
            out.triangles.push_back({m.faceVertices[at], m.faceVertices[at + static_cast<std::size_t>(k)],
                                     m.faceVertices[at + static_cast<std::size_t>(k) + 1]});
        at += static_cast<std::size_t>(n);
    }
    out.positions = std::move(m.positions);
    return out;
}

/// A validated control mesh with its OpenSubdiv topology.
class ControlMesh {
  public:
    /// Validates `d` and builds the topology. Throws MeshError naming the mesh and the
    /// offending face, vertex or edge: empty mesh, faces with fewer than 3 vertices, indices
    /// out of range, a face using a vertex twice, NaN/Inf positions or weights, non-manifold
    /// edges or vertices.
    explicit ControlMesh(MeshDescription d) : desc_(std::move(d)) { build(); }

    static ControlMesh fromObjText(const std::string& text, const std::string& name) {
        return ControlMesh(parseObj(text, name));
    }
    static ControlMesh fromObjFile(const std::string& path);

    const MeshDescription& description() const { return desc_; }
    const Far::TopologyRefiner& refiner() const { return *refiner_; }
    const Far::TopologyLevel& base() const { return refiner_->GetLevel(0); }
    const Far::PtexIndices& ptex() const { return *ptex_; }
    int ptexFaceCount() const { return ptex_->GetNumFaces(); }
    bool hasUVs() const { return !desc_.faceUVs.empty(); }
    /// A new, unrefined TopologyRefiner of this mesh, for callers that refine (BaseSurface
    /// refines adaptively; the one above stays at the base level).
    std::unique_ptr<Far::TopologyRefiner> createRefiner() const;
    /// First vertex of face f in the concatenated face-vertex arrays.
    int faceOffset(int f) const { return offsets_[static_cast<std::size_t>(f)]; }

  private:
    void build();
    MeshDescription desc_;
    std::vector<int> offsets_;
    std::shared_ptr<Far::TopologyRefiner> refiner_;
    std::shared_ptr<Far::PtexIndices> ptex_;
};

inline void ControlMesh::build() {
    const MeshDescription& d = desc_;
    const std::string& n = d.name;
    const int nv = static_cast<int>(d.positions.size());
    if (nv == 0 || d.faceSizes.empty()) throw MeshError(n + ": mesh has no vertices or no faces");
    for (std::size_t v = 0; v < d.positions.size(); ++v)
        if (!std::isfinite(d.positions[v].x) || !std::isfinite(d.positions[v].y) || !std::isfinite(d.positions[v].z))
            throw MeshError(n + ": vertex " + std::to_string(v + 1) + " has a NaN or infinite coordinate");
    int at = 0;
    for (std::size_t f = 0; f < d.faceSizes.size(); ++f) {
        const int size = d.faceSizes[f];
        offsets_.push_back(at);
        if (size < 3) throw MeshError(n + ": face " + std::to_string(f + 1) + " has fewer than 3 vertices");
        if (static_cast<std::size_t>(at + size) > d.faceVertices.size()) throw MeshError(n + ": face list truncated");
        for (int j = 0; j < size; ++j) {
            const int v = d.faceVertices[static_cast<std::size_t>(at + j)];
            if (v < 0 || v >= nv)
                throw MeshError(n + ": face " + std::to_string(f + 1) + " refers to vertex " + std::to_string(v + 1) +
                                ", but the mesh has " + std::to_string(nv) + " vertices");
            for (int i = 0; i < j; ++i)
                if (d.faceVertices[static_cast<std::size_t>(at + i)] == v)
                    throw MeshError(n + ": face " + std::to_string(f + 1) + " uses vertex " + std::to_string(v + 1) +
                                    " twice");
            if (!d.faceUVs.empty()) {
                const int t = d.faceUVs[static_cast<std::size_t>(at + j)];
                if (t < 0 || static_cast<std::size_t>(t) >= d.uvs.size())
                    throw MeshError(n + ": face " + std::to_string(f + 1) + " refers to a missing texture coordinate");
            }
        }
        at += size;
    }
    if (static_cast<std::size_t>(at) != d.faceVertices.size()) throw MeshError(n + ": face list has extra entries");
    for (const glm::dvec2& t : d.uvs)
        if (!std::isfinite(t.x) || !std::isfinite(t.y)) throw MeshError(n + ": a texture coordinate is NaN or infinite");
    for (int v : d.creaseVertexPairs)
        if (v < 0 || v >= nv) throw MeshError(n + ": crease refers to vertex " + std::to_string(v) + " (0-based), out of range");
    for (int v : d.cornerVertices)
        if (v < 0 || v >= nv) throw MeshError(n + ": corner refers to vertex " + std::to_string(v) + " (0-based), out of range");
    for (int f : d.holes)
        if (f < 0 || f >= static_cast<int>(d.faceSizes.size())) throw MeshError(n + ": hole refers to a missing face");
    for (float w : d.creaseWeights)
        if (!std::isfinite(w) || w < 0.0f) throw MeshError(n + ": crease sharpness must be finite and >= 0");
    for (float w : d.cornerWeights)
        if (!std::isfinite(w) || w < 0.0f) throw MeshError(n + ": corner sharpness must be finite and >= 0");

    refiner_ = createRefiner();
    const Far::TopologyLevel& l = refiner_->GetLevel(0);
    for (int e = 0; e < l.GetNumEdges(); ++e)
        if (l.IsEdgeNonManifold(e)) {
            auto ev = l.GetEdgeVertices(e);
            throw MeshError(n + ": non-manifold edge between vertices " + std::to_string(ev[0] + 1) + " and " +
                            std::to_string(ev[1] + 1) + " (" + std::to_string(l.GetEdgeFaces(e).size()) +
                            " faces, or faces with opposite orientation)");
        }
    for (int v = 0; v < l.GetNumVertices(); ++v)  // a vertex no face uses is harmless
        if (l.IsVertexNonManifold(v) && l.GetVertexFaces(v).size() > 0)
            throw MeshError(n + ": non-manifold vertex " + std::to_string(v + 1) + " (its faces do not form one fan)");
    ptex_ = std::make_shared<Far::PtexIndices>(*refiner_);
}

inline std::unique_ptr<Far::TopologyRefiner> ControlMesh::createRefiner() const {
    const MeshDescription& d = desc_;
    const std::string& n = d.name;
    Far::TopologyDescriptor td;
    td.numVertices = static_cast<int>(d.positions.size());
    td.numFaces = static_cast<int>(d.faceSizes.size());
    td.numVertsPerFace = d.faceSizes.data();
    td.vertIndicesPerFace = d.faceVertices.data();
    td.numCreases = static_cast<int>(d.creaseWeights.size());
    td.creaseVertexIndexPairs = d.creaseVertexPairs.data();
    td.creaseWeights = d.creaseWeights.data();
    td.numCorners = static_cast<int>(d.cornerWeights.size());
    td.cornerVertexIndices = d.cornerVertices.data();
    td.cornerWeights = d.cornerWeights.data();
    td.numHoles = static_cast<int>(d.holes.size());
    td.holeIndices = d.holes.data();
    Sdc::Options sdc;
    sdc.SetVtxBoundaryInterpolation(d.boundary);
    sdc.SetCreasingMethod(d.creasing);
    // OpenSubdiv reports errors through one process-wide callback (Far::SetErrorCallback) that
    // belongs to the application: dispmap never sets it. build() has rejected every input Far
    // is known to refuse, so a failure here is unexpected; Far's own message went to that
    // callback (or to stdout when none is set).
    Far::TopologyRefiner* r = Far::TopologyRefinerFactory<Far::TopologyDescriptor>::Create(
        td, Far::TopologyRefinerFactory<Far::TopologyDescriptor>::Options(Sdc::SCHEME_CATMARK, sdc));
    if (!r) throw MeshError(n + ": OpenSubdiv rejected the topology (its message went to OpenSubdiv's error callback)");
    return std::unique_ptr<Far::TopologyRefiner>(r);
}

/// 64-bit FNV-1a fingerprint of the mesh topology (face sizes and face vertices).
inline std::uint64_t topologyHash(const ControlMesh& mesh) {
    std::uint64_t h = 1469598103934665603ull;
    auto mix = [&](int v) {
        for (int b = 0; b < 4; ++b) {
            h ^= static_cast<std::uint64_t>((static_cast<unsigned>(v) >> (8 * b)) & 0xFFu);
            h *= 1099511628211ull;
        }
    };
    for (int s : mesh.description().faceSizes) mix(s);
    for (int v : mesh.description().faceVertices) mix(v);
    return h;
}

inline ControlMesh ControlMesh::fromObjFile(const std::string& path) {
    const std::vector<unsigned char> bytes = detail::readFileBytes(path, "mesh file");
    return fromObjText(std::string(bytes.begin(), bytes.end()), path);
}

} // namespace dispmap
