#pragma once
// `dispmap bench --only cages`: time and memory of each set-up stage against the size of the
// cage (docs/figures.md, "Production-size cages"): synthetic torus cages of 1k, 10k and 100k
// faces, quads (no extraordinary vertex) and triangles (every vertex extraordinary), at two
// isolation levels, with the growth exponents fitted; quad-dominant production-size cages (Spot
// refined 4 and 5 times: 46k and 187k quads, extraordinary vertices only where Spot has them);
// and dense triangle cages (the fandisk, the Stanford bunny) at isolation 2, 4 and 6 with the
// accuracy each level gives up.
#include <ostream>
#include <string>

#include "dispmap/surface/mesh.h"

namespace dispmap::figures {

struct CagesTableArgs {
    std::string dataDir;  ///< spot_control_mesh.obj (the quad-dominant cages: Spot refined)
    std::string denseDir; ///< cgal_fandisk.off, cgal_bunny00.off (rows skipped when absent)
    bool quick = false;   ///< 1k and 10k faces at isolation 2 only, no real cages (CI)
    std::string csv;      ///< also write the table as CSV
};

void printCagesTable(std::ostream& out, const CagesTableArgs& a);

/// A dense triangle mesh (OBJ, PLY, OFF: bake/dense_mesh.h's reader and checks) as a control
/// mesh of triangles.
ControlMesh denseCage(const std::string& path, const std::string& name);
/// The dense mesh at `path` decimated to about `faces` triangles (meshoptimizer, as `dispmap
/// bake` decimates), named "<label> decimated to N triangles": the 52k-triangle cage
/// is the bunny at 52000.
ControlMesh decimatedCage(const std::string& path, int faces, const std::string& label);
/// The diagonal of the bounding box of a cage's vertices.
double cageDiagonal(const ControlMesh& mesh);

} // namespace dispmap::figures
