#pragma once
// `dispmap maps --table`: reading, placing and prefiltering displacement maps, with the cost
// of each choice (docs/figures.md, "Displacement maps").
#include <memory>
#include <ostream>
#include <string>

#include "dispmap/core/height_image.h"
#include "dispmap/core/tileset.h"
#include "dispmap/surface/mesh.h"
#include "dispmap/surface/uv_map.h"

namespace dispmap::figures {

struct MapsTableArgs {
    std::string dataDir; ///< spot_control_mesh.obj and skimage_brick.png
    bool quick = false;  ///< a 512 map for the formats instead of 2048, one error-bound row, one frame a GPU row (CI)
    std::string device;  ///< Vulkan device for the GPU rows (name substring; "": the default)
};

void printMapsTable(std::ostream& out, const MapsTableArgs& a);

/// The brick map on Spot as the rendered rows show it: 2^k tiles (sub-faces 2^(k-1)), box
/// filter, wrapping, mid-level 0.5, scale 0.03 (maps --table's GPU rows, maps --seams), built
/// on `threads` threads (0: all cores).
TileSet spotBrickTiles(const ControlMesh& spot, std::shared_ptr<const UvMap> uvs, const HeightMaps& brick, int k, int threads = 0);

} // namespace dispmap::figures
