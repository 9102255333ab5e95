#pragma once
// Figures printed by `dispmap demo` and `dispmap bench`: tile statistics, the mip accuracy
// table, and the Google Benchmark timings registered in figures.cpp.
#include <ostream>
#include <sstream>
#include <utility>
#include <string>
#include <vector>

#include "dispmap/core/file_io.h"
#include "dispmap/surface/tile_builder.h"

namespace dispmap::figures {
/// A CSV table kept in memory and written atomically by commit() (nothing when the path is
/// empty), so that a failed run never leaves half a table.
struct CsvOut {
    std::string path;
    std::ostringstream text;
    CsvOut(std::string p, const char* header) : path(std::move(p)) { text << header << "\n"; }
    explicit operator bool() const { return !path.empty(); }
    template <typename T> CsvOut& operator<<(const T& x) {
        text << x;
        return *this;
    }
    void commit() {
        if (path.empty()) return;
        const std::string t = text.str();
        detail::writeFileAtomically(path, std::vector<unsigned char>(t.begin(), t.end()), "CSV table");
    }
};

/// The embedded default scene: a cage with extraordinary vertices of valence 3 and 5, a
/// triangle and a pentagon, and a procedural displacement (no files needed). Forwards to
/// dispmap/surface/builtin.h, where the meshes and functions live.
ControlMesh defaultMesh();
double defaultDisplacement(int face, double u, double v);
void printTileStats(std::ostream& out, const std::string& label, const TileSet& tiles, const BuildReport* report);
/// For Haar and B-wavelet mips: error of each level against the finest level, next to the
/// pyramid build time. Also writes `csvPath` if not empty.
void printMipTable(std::ostream& out, const std::string& csvPath);
/// Normals table: ns per evaluation of the base surface alone, displaced with approximate,
/// accurate and auto normals (auto at two tolerances; float and double), each with its angular
/// error against the double-precision accurate normal, on two scenes; ratios from the same run. Also writes
/// `csvPath` if not empty.
void printNormalTable(std::ostream& out, const std::string& csvPath);
/// Isolation level table: patches, build time, evaluation time and the base surface's error
/// near extraordinary vertices against level 10. Also writes `csvPath` if not empty.
void printIsolationTable(std::ostream& out, const std::string& csvPath);
/// Tessellation factor table: triangles, tessellation time and the distance of the mesh to the
/// displaced surface, for factors 2..64 with and without mips. Also writes `csvPath`.
void printTessellationTable(std::ostream& out, const std::string& csvPath);
/// Edit table: TileFitter::refit of one face against a full rebuild (tiles rewritten, time,
/// distance between the two). Also writes `csvPath` if not empty.
void printEditTable(std::ostream& out, const std::string& csvPath);
/// Runs the registered benchmarks with Google Benchmark's flags (e.g. --benchmark_filter=...).
int runBenchmarks(const std::vector<std::string>& flags);
} // namespace dispmap::figures
