#pragma once
// `dispmap tessellate -o out.glb / out.gltf`: a TriangleMesh as glTF 2.0 (tinygltf). Compiled
// code of the tool, not part of the header-only library, which keeps to OBJ and PLY
// (dispmap/io/mesh_writers.h).
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "dispmap/core/triangle_mesh.h"

namespace dispmap {

/// Writes `mesh` as glTF 2.0, atomically (core/file_io.h): binary `.glb`, or `.gltf` JSON with
/// the buffer embedded as a base64 data URI (the extension decides, in any case). Content: one
/// scene, one node, one mesh of one TRIANGLES primitive with float32 POSITION (with the min and
/// max the specification requires), float32 NORMAL (normalised), float32 TEXCOORD_0 when
/// `texcoords` is given (one per vertex, in the OBJ/PLY convention with the origin at the
/// bottom left; stored as (s, 1 - t), glTF's origin being the top left) and uint32 indices;
/// asset.version "2.0", asset.generator "dispmap". Throws ArgumentError, before anything is
/// written, for another extension, an empty mesh, arrays that disagree (normals, triangles,
/// texcoords), a non-finite or float-overflowing position or texcoord, a zero or non-finite
/// normal, or a buffer beyond the 32-bit sizes of GLB (and thus vertices or indices beyond
/// uint32); FileError naming the path when the file cannot be written.
void writeGltf(const TriangleMesh& mesh, const std::string& path, const std::vector<glm::dvec2>* texcoords = nullptr);

} // namespace dispmap
