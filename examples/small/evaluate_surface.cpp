// Evaluate a displaced Catmull-Clark surface on the CPU: a control mesh from an OBJ file, a
// height image mapped through the mesh's texture coordinates, and points f = s + N_s D with
// their normals, in double precision.
//
//   evaluate_surface MESH.obj HEIGHT.png [SCALE]
//
// Layers used: surface/ (OpenSubdiv) and io/ (libpng).
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <memory>

#include "dispmap/core/error.h"
#include "dispmap/io/png.h"
#include "dispmap/surface/base_surface.h"
#include "dispmap/surface/displaced_surface.h"
#include "dispmap/surface/mesh.h"
#include "dispmap/surface/tile_builder.h"
#include "dispmap/surface/map_source.h"

int main(int argc, char** argv) {
    if (argc < 3) {
        std::fprintf(stderr, "usage: %s MESH.obj HEIGHT.png [SCALE]\n", argv[0]);
        return 2;
    }
    try {
        const double scale = argc > 3 ? std::atof(argv[3]) : 0.05;
        const dispmap::ControlMesh mesh = dispmap::ControlMesh::fromObjFile(argv[1]);
        auto image = std::make_shared<const dispmap::HeightImage>(dispmap::readHeightPng(argv[2]));

        // Tiles of 2^4 x 2^4 sub-patches per quad face, fitted to the image (D = scale * h).
        const dispmap::TileSet tiles = dispmap::buildTiles(
            mesh, dispmap::uniformTileSizes(mesh, 4), dispmap::imageSource(mesh, image, scale, 0.0, /*wrap=*/true));
        const dispmap::BaseSurface base(mesh);
        const dispmap::DisplacedSurface surface(base, tiles);

        std::printf("%s: %d Ptex faces, %d tiles\n", argv[1], mesh.ptexFaceCount(), tiles.tileCount());
        for (int face = 0; face < mesh.ptexFaceCount() && face < 4; ++face) {
            const auto p = surface.evaluate<double>(face, 0.5, 0.5, dispmap::NormalMode::Accurate);
            std::printf("face %d (0.5, 0.5): f = (%.6f, %.6f, %.6f)  N = (%.4f, %.4f, %.4f)  D = %.6f\n", face,
                        p.position.x, p.position.y, p.position.z, p.normal.x, p.normal.y, p.normal.z, p.displacement.x);
        }
        return 0;
    } catch (const dispmap::Error& e) { // every dispmap failure names its input
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
}
