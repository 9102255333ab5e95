#pragma once
// `dispmap bake`: a dense mesh (scan, sculpt) to a base mesh (OBJ) + tile file + JSON report,
// by the simplification route (--base-faces) or the skeleton route (--skeleton); and
// `dispmap bake --table`, the accuracy-vs-time tables of docs/figures.md ("Baking a dense mesh").
#include <ostream>
#include <string>

namespace dispmap::figures {

struct BakeArgs {
    std::string input, skeleton, output, tiles, report, heatmap, scene;
    int baseFaces = 0, density = 16, threads = 0, iterations = 30, fitSamples = 8;
    double shell = 0.05, normalWeight = 0.05, adaptive = 0;
    bool quiet = false, oneSided = false;
    // --table
    bool table = false, quick = false;
    std::string csv, denseDir, skeletonDir, dataDir;
};

int bakeCommand(const BakeArgs& a);
void printBakeTable(std::ostream& out, const BakeArgs& a);

} // namespace dispmap::figures
