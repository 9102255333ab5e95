#include "swim.h"

#include "swimming.h"
#include "figures.h"

namespace dispmap::figures {

void printSwimFigure(std::ostream& out, const std::string& csvPath) {
    const ControlMesh mesh = defaultMesh();
    const BaseSurface base(mesh);
    const TileSet tiles = buildTiles(mesh, uniformTileSizes(mesh, 5), defaultDisplacement);
    const DisplacedSurface surface(base, tiles);
    const SwimOptions o;
    const std::vector<SwimRow> rows = measureSwimming(surface, o);
    out << "Swimming (texel-ratio rule): a uniform factor T swept " << o.tMin << ".." << o.tMax << " in steps dT = " << o.dT
        << ", fractional_even spacing;\n  default scene (" << base.faceCount() << " Ptex faces, tiles 2^5, sub-faces 2^4), "
        << o.samples << " fixed sample points x = (face, u, v);\n"
        << "  swim = |P_T(x) - P_{T+dT}(x)| / dT on the piecewise-linear tessellation, err = |P_T(x) - f(x)| against\n"
        << "  the finest surface; the max swim includes the jumps where the ring zipper re-triangulates (T-junctions)\n";
    printSwimTable(out, rows, csvPath);
}

} // namespace dispmap::figures
