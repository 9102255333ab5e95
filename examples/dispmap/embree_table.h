#pragma once
// `dispmap bench --only embree`: dispmap and Embree 3 side by side on the same cage and the same
// displacement D, one thread each, in one run (docs/figures.md, "Embree side by side"): set-up,
// tessellation at factors 2 to 64, and the accuracy of each tessellated surface against the
// double-precision displaced surface. Embree is a dependency of this benchmark (and of baking),
// never of the library's surface layers.
#include <ostream>
#include <string>

namespace dispmap::figures {

struct EmbreeTableArgs {
    std::string dataDir;  ///< spot_control_mesh.obj, skimage_brick.png, catmark_bishop.obj
    std::string denseDir; ///< cgal_fandisk.off, cgal_bunny00.off: the dense-cage rows (each skipped when absent)
    bool quick = false;   ///< Spot only, small tiles and factors (CI)
    std::string csv;      ///< also write the table as CSV
};

void printEmbreeTable(std::ostream& out, const EmbreeTableArgs& a);

} // namespace dispmap::figures
