// Meshes other tools can read: the PLY writer's texture coordinates (s, t), colours and Ptex
// (ptex_face, ptex_u, ptex_v) read back byte for byte and by assimp, the OBJ writer's `vt`
// read back by tinyobjloader, the dispmap tool's glTF 2.0 export (.glb, .gltf) read back by
// tinygltf (and assimp), and bad inputs refused before any file is written.
#include <catch2/catch.hpp>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <assimp/Importer.hpp>
#include <assimp/scene.h>
#include <tiny_gltf.h>
#include <tiny_obj_loader.h>

#include "dispmap/io/mesh_writers.h"
#include "dispmap/surface/tessellator.h"
#include "gltf_export.h"
#include "test_files.h"
#include "test_support.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_test_mesh_output {

using namespace dispmap;

namespace {

// A tessellation of catmark_nonquads (quads and n-gons, so several Ptex faces per control face)
// with bumps, factor 3: a few hundred vertices.
TriangleMesh sampleMesh() {
    const ControlMesh mesh = dmtest::shape("catmark_nonquads");
    const BaseSurface base(mesh);
    const TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 3), [](int f, double u, double v) {
        return 0.05 * std::sin(7.0 * u + 1.3 * f) * std::cos(5.0 * v - 0.7 * f);
    });
    const DisplacedSurface surface(base, tiles);
    return tessellate(surface, uniformTessFactors(base, 3.0));
}

// Texture coordinates of a made-up atlas: Ptex face f's square is cell (f mod 5, f / 5 mod 5) of
// a 5 x 5 grid; they reach 0 and 1 exactly, where the glTF flip t -> 1 - t shows.
std::vector<glm::dvec2> atlasTexcoords(const TriangleMesh& m) {
    std::vector<glm::dvec2> st(m.positions.size());
    for (std::size_t i = 0; i < st.size(); ++i) {
        const int f = m.faces[i];
        st[i] = glm::dvec2((f % 5 + m.uvs[i].x) / 5.0, ((f / 5) % 5 + m.uvs[i].y) / 5.0);
    }
    return st;
}

std::vector<glm::u8vec3> someColours(const TriangleMesh& m) {
    std::vector<glm::u8vec3> c(m.positions.size());
    for (std::size_t i = 0; i < c.size(); ++i)
        c[i] = glm::u8vec3(static_cast<unsigned char>(i % 251), static_cast<unsigned char>((7 * i) % 256),
                           static_cast<unsigned char>(255 - i % 256));
    return c;
}

float asFloat(double x) { return static_cast<float>(x); }

// A little-endian reader over bytes, from `at`.
struct Reader {
    const std::vector<unsigned char>& bytes;
    std::size_t at;
    std::uint32_t u32() {
        std::uint32_t w = 0;
        for (int i = 0; i < 4; ++i) w |= std::uint32_t{u8()} << (8 * i);
        return w;
    }
    float f32() { return std::bit_cast<float>(u32()); }
    std::int32_t i32() { return std::bit_cast<std::int32_t>(u32()); }
    unsigned char u8() {
        const unsigned char c = at < bytes.size() ? bytes[at] : static_cast<unsigned char>(0);
        ++at;
        return c;
    }
};

// The header of a binary PLY: the lines before end_header, and where the body starts.
struct PlyHeader {
    std::vector<std::string> lines;
    std::size_t body = 0;
};

PlyHeader plyHeader(const std::vector<unsigned char>& bytes) {
    PlyHeader h;
    const std::string text(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(std::min<std::size_t>(bytes.size(), 4096)));
    const std::size_t end = text.find("end_header\n");
    REQUIRE(end != std::string::npos);
    h.body = end + 11;
    std::istringstream in(text.substr(0, end));
    for (std::string line; std::getline(in, line);) h.lines.push_back(line);
    return h;
}

// The `property` lines of element `element` ("vertex"), as "type name".
std::vector<std::string> plyProperties(const PlyHeader& h, const std::string& element) {
    std::vector<std::string> props;
    bool inside = false;
    for (const std::string& line : h.lines) {
        if (line.rfind("element ", 0) == 0) inside = line.rfind("element " + element + " ", 0) == 0;
        else if (inside && line.rfind("property ", 0) == 0) props.push_back(line.substr(9));
    }
    return props;
}

// The bytes of accessor `a` of a loaded glTF model, checked to lie within its buffer.
const unsigned char* accessorData(const tinygltf::Model& model, int a, std::size_t elementBytes) {
    const tinygltf::Accessor& acc = model.accessors.at(static_cast<std::size_t>(a));
    const tinygltf::BufferView& view = model.bufferViews.at(static_cast<std::size_t>(acc.bufferView));
    const tinygltf::Buffer& buf = model.buffers.at(static_cast<std::size_t>(view.buffer));
    REQUIRE((view.byteStride == 0 || view.byteStride == elementBytes));
    REQUIRE(acc.byteOffset + acc.count * elementBytes <= view.byteLength);
    REQUIRE(view.byteOffset + view.byteLength <= buf.data.size());
    REQUIRE((view.byteOffset + acc.byteOffset) % 4 == 0);
    return buf.data.data() + view.byteOffset + acc.byteOffset;
}

float floatAt(const unsigned char* p, std::size_t i) {
    float x;
    std::memcpy(&x, p + 4 * i, 4);
    return x;
}

// Checks a loaded glTF model against the mesh (and texcoords, if any) it was written from.
void checkGltf(const tinygltf::Model& model, const TriangleMesh& m, const std::vector<glm::dvec2>* st) {
    CHECK(model.asset.version == "2.0");
    CHECK(model.asset.generator == "dispmap");
    REQUIRE(model.scenes.size() == 1);
    CHECK(model.defaultScene == 0);
    REQUIRE(model.scenes[0].nodes == std::vector<int>{0});
    REQUIRE(model.nodes.size() == 1);
    CHECK(model.nodes[0].mesh == 0);
    REQUIRE(model.meshes.size() == 1);
    REQUIRE(model.meshes[0].primitives.size() == 1);
    const tinygltf::Primitive& prim = model.meshes[0].primitives[0];
    CHECK(prim.mode == TINYGLTF_MODE_TRIANGLES);
    REQUIRE(prim.attributes.count("POSITION") == 1);
    REQUIRE(prim.attributes.count("NORMAL") == 1);
    REQUIRE(prim.attributes.count("TEXCOORD_0") == (st ? 1u : 0u));
    CHECK(prim.attributes.size() == (st ? 3u : 2u));
    const std::size_t n = m.positions.size();

    // POSITION: float VEC3, exactly the float-rounded positions, min/max exactly theirs.
    const int pa = prim.attributes.at("POSITION");
    const tinygltf::Accessor& pos = model.accessors.at(static_cast<std::size_t>(pa));
    CHECK(pos.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT);
    CHECK(pos.type == TINYGLTF_TYPE_VEC3);
    REQUIRE(pos.count == n);
    const unsigned char* p = accessorData(model, pa, 12);
    std::vector<double> lo(3, 1e300), hi(3, -1e300);
    bool same = true;
    for (std::size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) {
            const float want = asFloat(m.positions[i][c]);
            same = same && floatAt(p, 3 * i + static_cast<std::size_t>(c)) == want;
            lo[static_cast<std::size_t>(c)] = std::min(lo[static_cast<std::size_t>(c)], static_cast<double>(want));
            hi[static_cast<std::size_t>(c)] = std::max(hi[static_cast<std::size_t>(c)], static_cast<double>(want));
        }
    CHECK(same);
    CHECK(pos.minValues == lo);
    CHECK(pos.maxValues == hi);

    // NORMAL: float VEC3, the normalised normals (within float rounding), of unit length.
    const int na = prim.attributes.at("NORMAL");
    const tinygltf::Accessor& nor = model.accessors.at(static_cast<std::size_t>(na));
    CHECK(nor.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT);
    CHECK(nor.type == TINYGLTF_TYPE_VEC3);
    REQUIRE(nor.count == n);
    const unsigned char* q = accessorData(model, na, 12);
    bool normals = true;
    for (std::size_t i = 0; i < n; ++i) {
        const glm::dvec3 want = glm::normalize(m.normals[i]);
        const glm::dvec3 got(floatAt(q, 3 * i), floatAt(q, 3 * i + 1), floatAt(q, 3 * i + 2));
        normals = normals && glm::length(got - want) < 1e-6 && std::abs(glm::length(got) - 1.0) < 1e-6;
    }
    CHECK(normals);

    // TEXCOORD_0: float VEC2, (s, 1 - t) in float.
    if (st) {
        const int ta = prim.attributes.at("TEXCOORD_0");
        const tinygltf::Accessor& tc = model.accessors.at(static_cast<std::size_t>(ta));
        CHECK(tc.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT);
        CHECK(tc.type == TINYGLTF_TYPE_VEC2);
        REQUIRE(tc.count == n);
        const unsigned char* r = accessorData(model, ta, 8);
        bool texcoords = true;
        for (std::size_t i = 0; i < n; ++i)
            texcoords = texcoords && floatAt(r, 2 * i) == asFloat((*st)[i].x) && floatAt(r, 2 * i + 1) == asFloat(1.0 - (*st)[i].y);
        CHECK(texcoords);
    }

    // Indices: uint32 SCALAR, the triangles in order.
    const tinygltf::Accessor& idx = model.accessors.at(static_cast<std::size_t>(prim.indices));
    CHECK(idx.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
    CHECK(idx.type == TINYGLTF_TYPE_SCALAR);
    REQUIRE(idx.count == 3 * m.triangles.size());
    const unsigned char* ip = accessorData(model, prim.indices, 4);
    bool indices = true;
    for (std::size_t j = 0; j < m.triangles.size(); ++j)
        for (int c = 0; c < 3; ++c) {
            std::uint32_t k;
            std::memcpy(&k, ip + 4 * (3 * j + static_cast<std::size_t>(c)), 4);
            indices = indices && k == static_cast<std::uint32_t>(m.triangles[j][c]);
        }
    CHECK(indices);
    // The vertex attributes and the indices each have a view with their target.
    CHECK(model.bufferViews.at(static_cast<std::size_t>(pos.bufferView)).target == TINYGLTF_TARGET_ARRAY_BUFFER);
    CHECK(model.bufferViews.at(static_cast<std::size_t>(idx.bufferView)).target == TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    REQUIRE(model.buffers.size() == 1);
}

} // namespace

TEST_CASE("PLY with texture coordinates, colours and Ptex (face, u, v) reads back value for value", "[mesh_output]") {
    const TriangleMesh m = sampleMesh();
    REQUIRE(m.vertexCount() > 100);
    REQUIRE(m.faces.size() == m.positions.size());
    REQUIRE(m.uvs.size() == m.positions.size());
    const std::vector<glm::dvec2> st = atlasTexcoords(m);
    const std::vector<glm::u8vec3> colours = someColours(m);
    dmtest::TempDir dir("dispmap_mesh_output_");
    MeshWriteOptions o;
    o.texcoords = &st;
    o.colours = &colours;
    o.faceUV = true;
    writePly(m, dir.file("m.ply"), o);
    const std::vector<unsigned char> ply = dmtest::readBytes(dir.file("m.ply"));
    const PlyHeader h = plyHeader(ply);
    REQUIRE(h.lines.size() >= 3);
    CHECK(h.lines[0] == "ply");
    CHECK(h.lines[1] == "format binary_little_endian 1.0");
    CHECK(std::count(h.lines.begin(), h.lines.end(), "element vertex " + std::to_string(m.vertexCount())) == 1);
    CHECK(std::count(h.lines.begin(), h.lines.end(), "element face " + std::to_string(m.triangleCount())) == 1);
    // The layout writePly documents, in its order.
    CHECK(plyProperties(h, "vertex") == std::vector<std::string>{"float x", "float y", "float z", "float nx", "float ny", "float nz",
                                                                 "float s", "float t", "uchar red", "uchar green", "uchar blue",
                                                                 "int ptex_face", "float ptex_u", "float ptex_v"});
    CHECK(plyProperties(h, "face") == std::vector<std::string>{"list uchar uint vertex_indices"});
    REQUIRE(ply.size() == h.body + m.positions.size() * (24 + 8 + 3 + 12) + m.triangles.size() * 13);

    Reader r{ply, h.body};
    bool positions = true, texcoords = true, colour = true, ptex = true, triangles = true;
    for (std::size_t i = 0; i < m.positions.size(); ++i) {
        const glm::dvec3 &p = m.positions[i], &n = m.normals[i];
        for (double x : {p.x, p.y, p.z, n.x, n.y, n.z}) positions = positions && r.f32() == asFloat(x);
        texcoords = texcoords && r.f32() == asFloat(st[i].x);
        texcoords = texcoords && r.f32() == asFloat(st[i].y);
        for (int c = 0; c < 3; ++c) colour = colour && r.u8() == colours[i][c];
        ptex = ptex && r.i32() == m.faces[i];
        ptex = ptex && r.f32() == asFloat(m.uvs[i].x);
        ptex = ptex && r.f32() == asFloat(m.uvs[i].y);
    }
    for (const glm::ivec3& t : m.triangles) {
        triangles = triangles && r.u8() == 3;
        for (int c = 0; c < 3; ++c) triangles = triangles && r.u32() == static_cast<std::uint32_t>(t[c]);
    }
    CHECK(positions);
    CHECK(texcoords);
    CHECK(colour);
    CHECK(ptex);
    CHECK(triangles);
    CHECK(r.at == ply.size());

    // Only what was asked: Ptex (face, u, v) alone.
    MeshWriteOptions only;
    only.faceUV = true;
    writePly(m, dir.file("p.ply"), only);
    const std::vector<unsigned char> ply2 = dmtest::readBytes(dir.file("p.ply"));
    const PlyHeader h2 = plyHeader(ply2);
    CHECK(plyProperties(h2, "vertex") == std::vector<std::string>{"float x", "float y", "float z", "float nx", "float ny",
                                                                  "float nz", "int ptex_face", "float ptex_u", "float ptex_v"});
    CHECK(ply2.size() == h2.body + m.positions.size() * 36 + m.triangles.size() * 13);
    // The colours-only form of before still compiles and writes the same as the options.
    writePly(m, dir.file("c1.ply"), &colours);
    MeshWriteOptions co;
    co.colours = &colours;
    writePly(m, dir.file("c2.ply"), co);
    CHECK(dmtest::readBytes(dir.file("c1.ply")) == dmtest::readBytes(dir.file("c2.ply")));
    CHECK(dir.entries() == std::set<std::string>{"m.ply", "p.ply", "c1.ply", "c2.ply"}); // no temporaries left
}

TEST_CASE("assimp reads the PLY's s, t as texture coordinates, not the Ptex parameters", "[mesh_output]") {
    const TriangleMesh m = sampleMesh();
    const std::vector<glm::dvec2> st = atlasTexcoords(m);
    const std::vector<glm::u8vec3> colours = someColours(m);
    dmtest::TempDir dir("dispmap_mesh_output_assimp_");
    MeshWriteOptions o;
    o.texcoords = &st;
    o.colours = &colours;
    o.faceUV = true;
    writePly(m, dir.file("m.ply"), o);

    Assimp::Importer importer;
    const aiScene* scene = importer.ReadFile(dir.file("m.ply"), 0);
    INFO(importer.GetErrorString());
    REQUIRE(scene != nullptr);
    REQUIRE(scene->mNumMeshes == 1);
    const aiMesh* mesh = scene->mMeshes[0];
    REQUIRE(mesh->HasTextureCoords(0));
    CHECK(mesh->mNumUVComponents[0] == 2);
    CHECK(mesh->HasVertexColors(0));
    REQUIRE(mesh->mNumFaces == m.triangles.size());
    // Corner by corner (assimp may copy vertices per face): position and (s, t) as written.
    bool positions = true, texcoords = true;
    for (unsigned j = 0; j < mesh->mNumFaces; ++j) {
        const aiFace& f = mesh->mFaces[j];
        REQUIRE(f.mNumIndices == 3);
        for (unsigned c = 0; c < 3; ++c) {
            const unsigned k = f.mIndices[c];
            REQUIRE(k < mesh->mNumVertices);
            const std::size_t v = static_cast<std::size_t>(m.triangles[j][static_cast<int>(c)]);
            const aiVector3D& p = mesh->mVertices[k];
            const aiVector3D& t = mesh->mTextureCoords[0][k];
            positions = positions && p.x == asFloat(m.positions[v].x) && p.y == asFloat(m.positions[v].y) &&
                        p.z == asFloat(m.positions[v].z);
            texcoords = texcoords && t.x == asFloat(st[v].x) && t.y == asFloat(st[v].y);
        }
    }
    CHECK(positions);
    CHECK(texcoords);
}

TEST_CASE("OBJ with vt reads back in tinyobjloader: texcoords and the faces' texcoord indices", "[mesh_output]") {
    const TriangleMesh m = sampleMesh();
    const std::vector<glm::dvec2> st = atlasTexcoords(m);
    dmtest::TempDir dir("dispmap_mesh_output_obj_");
    MeshWriteOptions o;
    o.texcoords = &st;
    writeObj(m, dir.file("m.obj"), o);

    tinyobj::ObjReaderConfig config;
    config.triangulate = false;
    tinyobj::ObjReader reader;
    REQUIRE(reader.ParseFromFile(dir.file("m.obj"), config));
    INFO(reader.Warning());
    const tinyobj::attrib_t& attrib = reader.GetAttrib();
    REQUIRE(attrib.vertices.size() == 3 * m.positions.size());
    REQUIRE(attrib.normals.size() == 3 * m.normals.size());
    REQUIRE(attrib.texcoords.size() == 2 * st.size());
    bool texcoords = true;
    for (std::size_t i = 0; i < st.size(); ++i)
        for (std::size_t c = 0; c < 2; ++c) {
            const double want = st[i][static_cast<int>(c)];
            texcoords = texcoords && std::abs(static_cast<double>(attrib.texcoords[2 * i + c]) - want) <= 1e-12;
        }
    CHECK(texcoords);
    REQUIRE(reader.GetShapes().size() == 1);
    const tinyobj::mesh_t& shape = reader.GetShapes()[0].mesh;
    REQUIRE(shape.num_face_vertices.size() == m.triangles.size());
    REQUIRE(shape.indices.size() == 3 * m.triangles.size());
    bool faces = true;
    for (std::size_t j = 0; j < m.triangles.size(); ++j) {
        faces = faces && shape.num_face_vertices[j] == 3;
        for (int c = 0; c < 3; ++c) {
            const tinyobj::index_t& x = shape.indices[3 * j + static_cast<std::size_t>(c)];
            faces = faces && x.vertex_index == m.triangles[j][c] && x.texcoord_index == m.triangles[j][c] &&
                    x.normal_index == m.triangles[j][c];
        }
    }
    CHECK(faces);
    // The `vt` decimals are the shortest round-trip ones: read as double, bit for bit.
    const std::vector<unsigned char> bytes = dmtest::readBytes(dir.file("m.obj"));
    std::istringstream lines(std::string(bytes.begin(), bytes.end()));
    std::size_t vts = 0;
    bool exact = true, faceForm = true;
    for (std::string line; std::getline(lines, line);) {
        if (line.rfind("f ", 0) == 0) faceForm = faceForm && line.find("//") == std::string::npos;
        if (line.rfind("vt ", 0) != 0) continue;
        glm::dvec2 x(0.0);
        const char* b = line.data() + 3;
        const char* e = line.data() + line.size();
        auto r1 = std::from_chars(b, e, x.x);
        exact = exact && r1.ec == std::errc() && r1.ptr < e && *r1.ptr == ' ';
        auto r2 = std::from_chars(r1.ptr + 1, e, x.y);
        exact = exact && r2.ec == std::errc() && r2.ptr == e && vts < st.size() && x == st[vts];
        ++vts;
    }
    CHECK(vts == st.size());
    CHECK(exact);
    CHECK(faceForm); // f a/a/a, not a//a
}

TEST_CASE("glTF export: .glb and .gltf read back in tinygltf", "[mesh_output]") {
    const TriangleMesh m = sampleMesh();
    const std::vector<glm::dvec2> st = atlasTexcoords(m);
    dmtest::TempDir dir("dispmap_mesh_output_gltf_");
    tinygltf::TinyGLTF loader;
    std::string err, warn;

    writeGltf(m, dir.file("m.glb"), &st);
    const std::vector<unsigned char> glb = dmtest::readBytes(dir.file("m.glb"));
    REQUIRE(glb.size() > 20);
    CHECK(std::string(glb.begin(), glb.begin() + 4) == "glTF");
    Reader r{glb, 4};
    CHECK(r.u32() == 2);          // version
    CHECK(r.u32() == glb.size()); // length
    CHECK(glb.size() % 4 == 0);
    tinygltf::Model model;
    const bool loaded = loader.LoadBinaryFromFile(&model, &err, &warn, dir.file("m.glb"));
    INFO(err << warn);
    REQUIRE(loaded);
    CHECK(warn.empty());
    checkGltf(model, m, &st);
    {
        // assimp too reads the .glb, and turns the stored (s, 1 - t) back into (s, t).
        Assimp::Importer importer;
        const aiScene* scene = importer.ReadFile(dir.file("m.glb"), 0);
        INFO(importer.GetErrorString());
        REQUIRE(scene != nullptr);
        REQUIRE(scene->mNumMeshes == 1);
        const aiMesh* mesh = scene->mMeshes[0];
        REQUIRE(mesh->HasTextureCoords(0));
        REQUIRE(mesh->mNumFaces == m.triangles.size());
        bool texcoords = true;
        for (unsigned j = 0; j < mesh->mNumFaces; ++j)
            for (unsigned c = 0; c < 3 && mesh->mFaces[j].mNumIndices == 3; ++c) {
                const std::size_t v = static_cast<std::size_t>(m.triangles[j][static_cast<int>(c)]);
                const aiVector3D& t = mesh->mTextureCoords[0][mesh->mFaces[j].mIndices[c]];
                texcoords = texcoords && std::abs(static_cast<double>(t.x) - st[v].x) < 1e-6 &&
                            std::abs(static_cast<double>(t.y) - st[v].y) < 1e-6;
            }
        CHECK(texcoords);
    }

    writeGltf(m, dir.file("m.gltf"), &st);
    const std::vector<unsigned char> text = dmtest::readBytes(dir.file("m.gltf"));
    const std::string json(text.begin(), text.end());
    CHECK(json.find("\"uri\": \"data:application/octet-stream;base64,") != std::string::npos); // embedded, no .bin
    tinygltf::Model model2;
    const bool loaded2 = loader.LoadASCIIFromFile(&model2, &err, &warn, dir.file("m.gltf"));
    INFO(err << warn);
    REQUIRE(loaded2);
    checkGltf(model2, m, &st);

    // Without texcoords: no TEXCOORD_0; the extension in capitals is the same format.
    writeGltf(m, dir.file("plain.GLB"));
    tinygltf::Model model3;
    const bool loaded3 = loader.LoadBinaryFromFile(&model3, &err, &warn, dir.file("plain.GLB"));
    INFO(err << warn);
    REQUIRE(loaded3);
    checkGltf(model3, m, nullptr);
    CHECK(dir.entries() == std::set<std::string>{"m.glb", "m.gltf", "plain.GLB"}); // no .bin, no temporaries
}

TEST_CASE("mesh output: bad texcoords, colours and glTF paths are refused before anything is written", "[mesh_output]") {
    const TriangleMesh m = sampleMesh();
    const std::vector<glm::dvec2> st = atlasTexcoords(m);
    const std::vector<glm::u8vec3> colours = someColours(m);
    dmtest::TempDir dir("dispmap_mesh_output_bad_");
    const std::string ply = dir.file("x.ply"), obj = dir.file("x.obj"), glb = dir.file("x.glb"), gltf = dir.file("x.gltf");
    const std::string n = std::to_string(m.vertexCount());

    std::vector<glm::dvec2> shortSt(st.begin(), st.end() - 1);
    MeshWriteOptions o;
    o.texcoords = &shortSt;
    REQUIRE_THROWS_WITH(writePly(m, ply, o), Catch::Contains(std::to_string(shortSt.size()) + " texture coordinates for " + n + " vertices"));
    REQUIRE_THROWS_AS(writeObj(m, obj, o), ArgumentError);
    REQUIRE_THROWS_AS(writeGltf(m, glb, &shortSt), ArgumentError);
    std::vector<glm::dvec2> longSt = st;
    longSt.push_back(glm::dvec2(0.5));
    o.texcoords = &longSt;
    REQUIRE_THROWS_AS(writePly(m, ply, o), ArgumentError);

    std::vector<glm::dvec2> nanSt = st;
    nanSt[7].y = std::nan("");
    o.texcoords = &nanSt;
    REQUIRE_THROWS_WITH(writePly(m, ply, o), Catch::Contains("texture coordinates of vertex 7 has nan"));
    REQUIRE_THROWS_WITH(writeObj(m, obj, o), Catch::Contains("of vertex 7"));
    REQUIRE_THROWS_WITH(writeGltf(m, gltf, &nanSt), Catch::Contains("of vertex 7"));
    nanSt[7].y = std::numeric_limits<double>::infinity();
    REQUIRE_THROWS_AS(writeObj(m, obj, o), ArgumentError);
    nanSt[7].y = 1e39; // finite, but no float: OBJ takes it, PLY and glTF cannot
    REQUIRE_THROWS_WITH(writePly(m, ply, o), Catch::Contains("not a finite float"));
    REQUIRE_THROWS_AS(writeGltf(m, glb, &nanSt), ArgumentError);

    std::vector<glm::u8vec3> shortColours(colours.begin(), colours.end() - 1);
    REQUIRE_THROWS_WITH(writePly(m, ply, &shortColours), Catch::Contains(std::to_string(shortColours.size()) + " colours for " + n));
    MeshWriteOptions c;
    c.colours = &shortColours;
    REQUIRE_THROWS_AS(writePly(m, ply, c), ArgumentError);
    c.colours = &colours; // right count, but OBJ holds no colours
    REQUIRE_THROWS_WITH(writeObj(m, obj, c), Catch::Contains("OBJ holds no vertex colours"));
    MeshWriteOptions f;
    f.faceUV = true;
    REQUIRE_THROWS_AS(writeObj(m, obj, f), ArgumentError);
    TriangleMesh noFaces = m;
    noFaces.faces.pop_back();
    REQUIRE_THROWS_WITH(writePly(noFaces, ply, f), Catch::Contains("Ptex faces for"));
    TriangleMesh nanUV = m;
    nanUV.uvs[3].x = std::nan("");
    REQUIRE_THROWS_WITH(writePly(nanUV, ply, f), Catch::Contains("Ptex (u, v) of vertex 3"));

    REQUIRE_THROWS_WITH(writeGltf(m, dir.file("x.gltx"), &st), Catch::Contains("must end in .glb (binary) or .gltf"));
    REQUIRE_THROWS_AS(writeGltf(m, dir.file("x.obj")), ArgumentError);
    REQUIRE_THROWS_AS(writeGltf(m, dir.file("glb")), ArgumentError);
    REQUIRE_THROWS_WITH(writeGltf(TriangleMesh{}, glb), Catch::Contains("empty mesh"));
    TriangleMesh zeroNormal = m;
    zeroNormal.normals[2] = glm::dvec3(0.0);
    REQUIRE_THROWS_WITH(writeGltf(zeroNormal, glb), Catch::Contains("normal of vertex 2"));
    TriangleMesh farAway = m;
    farAway.positions[4].z = 1e300;
    REQUIRE_THROWS_WITH(writeGltf(farAway, gltf), Catch::Contains("position of vertex 4"));
    TriangleMesh broken = m;
    broken.triangles.back().y = m.vertexCount();
    REQUIRE_THROWS_WITH(writeGltf(broken, glb), Catch::Contains("refers to vertex"));
    REQUIRE_THROWS_WITH(writeGltf(m, dir.file("no/such/dir/x.glb")), Catch::Contains("cannot write glTF mesh"));
    CHECK(dir.entries().empty()); // no output, no temporaries

    // A refused write leaves the file that was there as it was.
    writePly(m, ply);
    const std::vector<unsigned char> before = dmtest::readBytes(ply);
    o.texcoords = &shortSt;
    REQUIRE_THROWS_AS(writePly(m, ply, o), ArgumentError);
    CHECK(dmtest::readBytes(ply) == before);
    CHECK(dir.entries() == std::set<std::string>{"x.ply"});
}

} // namespace dmtest_test_mesh_output
