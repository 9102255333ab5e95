#pragma once
// ControlMesh: a Catmull-Clark control mesh read from OBJ (OpenSubdiv's regression-shape
// dialect, tags included), validated, and turned into OpenSubdiv's Far::TopologyRefiner and
// Far::PtexIndices. Topology questions are answered by OpenSubdiv; this file only carries the
// data in and checks it.
//
// Errors: every input Far would refuse or warn about is refused here first, with a MeshError
// naming the file and (for OBJ text) the 1-based line. OpenSubdiv reports its own errors and
// warnings through one process-wide callback that belongs to the application (dispmap never
// sets it), so checking beforehand is the only way to keep its messages out of our error path.
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include <glm/glm.hpp>
#include <opensubdiv/far/ptexIndices.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>
#include <opensubdiv/vtr/types.h>
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
    /// Material names (OBJ `usemtl`) in the order of their first use, and each face's index
    /// into them (-1: a face before any `usemtl`). Both empty when the file names no material.
    /// Nothing of the surface: what several mesostructures are placed by (scene/meso.h).
    std::vector<std::string> materials;
    std::vector<int> faceMaterials;
    Sdc::Options::VtxBoundaryInterpolation boundary = Sdc::Options::VTX_BOUNDARY_EDGE_ONLY;
    Sdc::Options::CreasingMethod creasing = Sdc::Options::CREASE_UNIFORM;
    /// `t smoothtriangles`: Catmark's rule for triangles (TRI_SUB_SMOOTH changes the surface).
    Sdc::Options::TriangleSubdivision triangles = Sdc::Options::TRI_SUB_CATMARK;
    /// `t facevaryinginterpolateboundary`: how the texture coordinates subdivide, the rule
    /// UvMap's UvInterpolation::Mesh uses (surface/uv_map.h). Default: linear (FVAR_LINEAR_ALL).
    Sdc::Options::FVarLinearInterpolation fvarLinear = Sdc::Options::FVAR_LINEAR_ALL;
};

namespace detail {

/// The first crease pair (index into the pairs) of `d` that is not an edge of its faces, or -1.
/// The face list must be consistent (sizes summing to the vertex list) and the pairs in range.
inline long firstCreaseNotEdge(const MeshDescription& d) {
    if (d.creaseVertexPairs.empty()) return -1;
    auto key = [](int a, int b) {
        return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(std::min(a, b))) << 32) |
               static_cast<std::uint32_t>(std::max(a, b));
    };
    std::unordered_set<std::uint64_t> edges;
    for (std::size_t f = 0, o = 0; f < d.faceSizes.size(); o += static_cast<std::size_t>(d.faceSizes[f]), ++f) {
        const std::size_t size = static_cast<std::size_t>(d.faceSizes[f]);
        for (std::size_t j = 0; j < size; ++j) edges.insert(key(d.faceVertices[o + j], d.faceVertices[o + (j + 1) % size]));
    }
    for (std::size_t i = 0; 2 * i + 1 < d.creaseVertexPairs.size(); ++i)
        if (!edges.count(key(d.creaseVertexPairs[2 * i], d.creaseVertexPairs[2 * i + 1]))) return static_cast<long>(i);
    return -1;
}
inline std::string creaseNotEdge(const MeshDescription& d, std::size_t i) {
    return "crease pair (" + std::to_string(d.creaseVertexPairs[2 * i]) + ", " + std::to_string(d.creaseVertexPairs[2 * i + 1]) +
           ") (0-based) is not an edge of the mesh";
}

/// Where an OBJ statement was read: "name:line: reason" messages.
struct ObjPlace {
    const std::string& name;
    long line = 0;
    [[noreturn]] void fail(const std::string& why) const {
        throw MeshError(name + ":" + std::to_string(line) + ": " + why);
    }
};

/// A token for an error message: quoted, cut short (a fuzzed or binary file may have long ones).
inline std::string objQuote(std::string_view s) {
    // Appended piecewise: GCC 12 at -O3 reports a false -Wstringop-overflow for "'" + string.
    std::string q(1, '\'');
    q.append(s.data(), std::min<std::size_t>(s.size(), 40));
    q.append(s.size() > 40 ? "...'" : "'");
    return q;
}

/// A real number of an OBJ file. The mesh keeps double precision (tinyobjloader's double build),
/// but the float evaluation and the renderer hold coordinates in single precision, so a value
/// near or beyond float's range (3.4e38) is refused here, where the line is known, rather than
/// becoming infinity there.
inline double objReal(const ObjPlace& at, std::string_view tok, const std::string& what) {
    std::string_view s = tok;
    if (s.size() > 1 && s[0] == '+' && s[1] != '+' && s[1] != '-') s.remove_prefix(1);
    double x = 0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), x);
    if (ec == std::errc::result_out_of_range) at.fail(what + " " + objQuote(tok) + " is out of range");
    if (ec != std::errc() || end != s.data() + s.size()) at.fail(what + " " + objQuote(tok) + " is not a number");
    if (std::isnan(x)) at.fail(what + " " + objQuote(tok) + " is NaN");
    if (std::isinf(x)) at.fail(what + " " + objQuote(tok) + " is infinite");
    if (std::abs(x) > 1e38) at.fail(what + " " + objQuote(tok) + " is out of range (beyond 1e38, which single precision cannot hold)");
    return x;
}

/// An integer of an OBJ file (an index or a tag value).
inline int objInt(const ObjPlace& at, std::string_view tok, const std::string& what) {
    std::string_view s = tok;
    if (s.size() > 1 && s[0] == '+' && s[1] != '+' && s[1] != '-') s.remove_prefix(1);
    int x = 0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), x);
    if (ec == std::errc::result_out_of_range) at.fail(what + " " + objQuote(tok) + " is out of range");
    if (ec != std::errc() || end != s.data() + s.size()) at.fail(what + " " + objQuote(tok) + " is not an integer");
    return x;
}

/// The OBJ text as dispmap reads it: checked statement by statement, the v, vt, vn and f
/// statements kept (normalised, on their own line numbers) for tinyobjloader, everything
/// else read here.
struct ObjScan {
    std::string forTinyobj;              ///< the v/vt/vn/f statements only; other lines empty
    std::vector<double> positions, uvs;  ///< as read here, to check tinyobjloader's values
    int normals = 0;
    std::vector<long> faceLines;         ///< line of each face
    MeshDescription d;                   ///< faces, tags and options (positions and uvs from tinyobjloader)
    std::vector<long> creaseLines, cornerLines, holeLines; ///< line of each crease pair, corner, hole
};

/// The tag statements of OpenSubdiv's shapes, `t name nint/nfloat/nstring ints floats strings`
/// with 0-based indices, read as OpenSubdiv's regression harness reads them (its GetSdcOptions
/// and assignComponentTags), except that nothing it would skip with a printed complaint is
/// skipped here: that is an error.
inline void objTag(const ObjPlace& at, const std::vector<std::string_view>& tok, ObjScan& s, std::vector<long>& optionLines) {
    if (tok.size() < 3) at.fail("tag needs a name and a count triple 'nint/nfloat/nstring'");
    const std::string name(tok[1]);
    const std::string tag = "tag '" + std::string(tok[1].substr(0, 40)) + "'";
    // The count triple, exactly three non-negative integers, and as many values as they say.
    const long long given = static_cast<long long>(tok.size()) - 3;
    long long count[3] = {0, 0, 0};
    {
        std::string_view c = tok[2];
        for (int k = 0; k < 3; ++k) {
            const std::size_t slash = k < 2 ? c.find('/') : std::string_view::npos;
            if (k < 2 && slash == std::string_view::npos) at.fail(tag + ": counts " + objQuote(tok[2]) + " are not 'nint/nfloat/nstring'");
            const std::string_view part = c.substr(0, slash);
            const auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), count[k]);
            if (ec != std::errc() || end != part.data() + part.size() || count[k] < 0)
                at.fail(tag + ": counts " + objQuote(tok[2]) + " are not 'nint/nfloat/nstring'");
            if (k < 2) c.remove_prefix(slash + 1);
        }
    }
    // A count beyond any file's size is not summed (no overflow): it cannot match anyway.
    constexpr long long kHuge = 1LL << 48;
    const bool huge = count[0] > kHuge || count[1] > kHuge || count[2] > kHuge;
    if (huge || count[0] + count[1] + count[2] != given)
        at.fail(tag + " declares " + std::to_string(count[0]) + " integers, " + std::to_string(count[1]) + " floats and " +
                std::to_string(count[2]) + " strings" +
                (huge ? std::string() : " (" + std::to_string(count[0] + count[1] + count[2]) + " values)") + ", but " +
                std::to_string(given) + " values follow");
    const std::size_t ni = static_cast<std::size_t>(count[0]), nf = static_cast<std::size_t>(count[1]);
    std::vector<int> ints;
    std::vector<float> floats;
    std::vector<std::string_view> strings;
    for (std::size_t i = 0; i < ni; ++i) ints.push_back(objInt(at, tok[3 + i], tag + ": integer"));
    for (std::size_t i = 0; i < nf; ++i) {
        const double x = objReal(at, tok[3 + ni + i], tag + ": value");
        if (x < 0) at.fail(tag + ": value " + objQuote(tok[3 + ni + i]) + " is negative");
        floats.push_back(static_cast<float>(x));
    }
    for (std::size_t i = 3 + ni + nf; i < tok.size(); ++i) strings.push_back(tok[i]);
    auto shape = [&](std::size_t wi, std::size_t wf, std::size_t ws, const char* what) {
        if (ints.size() != wi || floats.size() != wf || strings.size() != ws) at.fail(tag + " expects " + what);
    };
    // Options: one tag each; a second one is refused rather than silently overriding the first.
    auto once = [&](std::size_t option) {
        if (optionLines[option] != 0)
            at.fail(tag + " is given twice (first at line " + std::to_string(optionLines[option]) + ")");
        optionLines[option] = at.line;
    };
    MeshDescription& d = s.d;
    if (name == "crease") {
        // Vertex pairs, then one sharpness for all pairs or one per pair (in pair order; the
        // regression harness indexes per-pair values differently, but none of OpenSubdiv's
        // shapes gives more than one pair per tag).
        if (ints.empty() || ints.size() % 2 != 0) at.fail(tag + " needs vertex pairs (an even, nonzero number of integers)");
        const std::size_t n = ints.size() / 2;
        if (!strings.empty() || (floats.size() != 1 && floats.size() != n))
            at.fail(tag + " needs one sharpness, or one per vertex pair (" + std::to_string(n) + "), and no strings");
        for (std::size_t i = 0; i < n; ++i) {
            d.creaseVertexPairs.push_back(ints[2 * i]);
            d.creaseVertexPairs.push_back(ints[2 * i + 1]);
            d.creaseWeights.push_back(floats[floats.size() == 1 ? 0 : i]);
            s.creaseLines.push_back(at.line);
        }
    } else if (name == "corner") {
        if (ints.empty() || !strings.empty() || (floats.size() != 1 && floats.size() != ints.size()))
            at.fail(tag + " needs vertices and one sharpness, or one per vertex, and no strings");
        for (std::size_t i = 0; i < ints.size(); ++i) {
            d.cornerVertices.push_back(ints[i]);
            d.cornerWeights.push_back(floats[floats.size() == 1 ? 0 : i]);
            s.cornerLines.push_back(at.line);
        }
    } else if (name == "hole") {
        if (ints.empty() || !floats.empty() || !strings.empty()) at.fail(tag + " needs face indices only");
        for (int f : ints) {
            d.holes.push_back(f);
            s.holeLines.push_back(at.line);
        }
    } else if (name == "interpolateboundary") {
        shape(1, 0, 0, "one integer: 0 (none), 1 (edge and corner) or 2 (edge only)");
        once(0);
        if (ints[0] < 0 || ints[0] > 2) at.fail(tag + ": " + std::to_string(ints[0]) + " is not 0, 1 or 2");
        d.boundary = ints[0] == 0   ? Sdc::Options::VTX_BOUNDARY_NONE
                     : ints[0] == 1 ? Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER
                                    : Sdc::Options::VTX_BOUNDARY_EDGE_ONLY;
    } else if (name == "creasemethod") {
        shape(0, 0, 1, "one string, 'normal' or 'chaikin'");
        once(1);
        if (strings[0] == "normal")
            d.creasing = Sdc::Options::CREASE_UNIFORM;
        else if (strings[0] == "chaikin")
            d.creasing = Sdc::Options::CREASE_CHAIKIN;
        else
            at.fail(tag + ": " + objQuote(strings[0]) + " is not 'normal' or 'chaikin'");
    } else if (name == "smoothtriangles") {
        shape(0, 0, 1, "one string, 'catmark' or 'smooth'");
        once(2);
        if (strings[0] == "catmark")
            d.triangles = Sdc::Options::TRI_SUB_CATMARK;
        else if (strings[0] == "smooth")
            d.triangles = Sdc::Options::TRI_SUB_SMOOTH;
        else
            at.fail(tag + ": " + objQuote(strings[0]) + " is not 'catmark' or 'smooth'");
    } else if (name == "facevaryinginterpolateboundary") {
        shape(1, 0, 0, "one integer, 0 to 5");
        once(3);
        static constexpr Sdc::Options::FVarLinearInterpolation modes[] = {
            Sdc::Options::FVAR_LINEAR_NONE,          Sdc::Options::FVAR_LINEAR_CORNERS_ONLY,
            Sdc::Options::FVAR_LINEAR_CORNERS_PLUS1, Sdc::Options::FVAR_LINEAR_CORNERS_PLUS2,
            Sdc::Options::FVAR_LINEAR_BOUNDARIES,    Sdc::Options::FVAR_LINEAR_ALL};
        if (ints[0] < 0 || ints[0] > 5) at.fail(tag + ": " + std::to_string(ints[0]) + " is not 0 to 5");
        d.fvarLinear = modes[ints[0]];
    } else if (name == "facevaryingpropagatecorners") {
        // Hbr's option; Sdc (OpenSubdiv 3) has no equivalent, and the regression harness
        // asserts on it.
        at.fail(tag + " is not supported: OpenSubdiv 3 has no equivalent option");
    } else {
        at.fail("unknown " + tag + " (known: crease, corner, hole, interpolateboundary, creasemethod, smoothtriangles, "
                "facevaryinginterpolateboundary)");
    }
}

/// One face corner, `v`, `v/vt`, `v//vn` or `v/vt/vn` (1-based, or negative: relative to the
/// elements read so far), as 0-based indices (-1 where absent). Positive indices may refer
/// forward; their range is checked at the end of the file.
struct ObjCorner {
    int v = -1, vt = -1, vn = -1;
};
inline ObjCorner objCorner(const ObjPlace& at, std::string_view tok, int nv, int nvt, int nvn) {
    std::string_view part[3];
    int parts = 0;
    for (std::string_view rest = tok;;) {
        if (parts == 3) at.fail("face corner " + objQuote(tok) + " is not v, v/vt, v//vn or v/vt/vn");
        const std::size_t slash = rest.find('/');
        part[parts++] = rest.substr(0, slash);
        if (slash == std::string_view::npos) break;
        rest.remove_prefix(slash + 1);
    }
    if (part[0].empty() || (parts == 2 && part[1].empty()) || (parts == 3 && part[2].empty()))
        at.fail("face corner " + objQuote(tok) + " is not v, v/vt, v//vn or v/vt/vn");
    auto index = [&](std::string_view p, int count, const char* what) {
        const int i = objInt(at, p, std::string(what) + " index");
        if (i == 0) at.fail(std::string(what) + " index 0 in " + objQuote(tok) + " (OBJ indices start at 1)");
        if (i > 0) return i - 1;
        if (-static_cast<long long>(i) > count)
            at.fail("relative " + std::string(what) + " index " + std::to_string(i) + " in " + objQuote(tok) + ", but only " +
                    std::to_string(count) + " precede it");
        return count + i;
    };
    ObjCorner c;
    c.v = index(part[0], nv, "vertex");
    if (parts >= 2 && !part[1].empty()) c.vt = index(part[1], nvt, "texture coordinate");
    if (parts == 3) c.vn = index(part[2], nvn, "normal");
    return c;
}

inline ObjScan scanObj(const std::string& text, const std::string& name) {
    ObjScan s;
    MeshDescription& d = s.d;
    d.name = name;
    s.forTinyobj.reserve(text.size());
    ObjPlace at{name, 0};
    std::vector<std::string_view> tok;
    std::vector<long> optionLines(4, 0);
    int nv = 0, nvt = 0;
    std::vector<int> faceNormals; // per face corner, for the range check at the end
    struct Reference {            // a corner of an (ignored) line or point statement
        long line;
        ObjCorner c;
    };
    std::vector<Reference> ignored;
    long firstFaceLine = 0;
    bool firstFaceUV = false;
    int material = -1; // the last usemtl's index into d.materials
    std::unordered_map<std::string, int> materialIndex;
    std::size_t pos = 0;
    // A UTF-8 byte order mark is text; a byte below 0x20 other than \t \n \r \f \v, or DEL,
    // is not.
    if (text.compare(0, 3, "\xEF\xBB\xBF") == 0) pos = 3;
    while (pos < text.size()) {
        ++at.line;
        // One line, ended by \n, \r\n or a lone \r (tinyobjloader's line ends).
        std::size_t end = pos;
        for (; end < text.size() && text[end] != '\n' && text[end] != '\r'; ++end) {
            const unsigned char c = static_cast<unsigned char>(text[end]);
            if ((c < 0x20 && c != '\t' && c != '\f' && c != '\v') || c == 0x7F) {
                static const char hex[] = "0123456789ABCDEF";
                at.fail(std::string("binary or NUL byte 0x") + hex[c >> 4] + hex[c & 15] + " at column " +
                        std::to_string(end - pos + 1) + ": not a text OBJ file");
            }
        }
        const std::string_view line(text.data() + pos, end - pos);
        pos = end;
        if (pos < text.size()) pos += text[pos] == '\r' && pos + 1 < text.size() && text[pos + 1] == '\n' ? 2u : 1u;
        // Tokens, separated by blanks; a token that starts with # starts a comment.
        tok.clear();
        auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\f' || c == '\v'; };
        for (std::size_t i = 0; i < line.size();) {
            while (i < line.size() && blank(line[i])) ++i;
            if (i == line.size() || line[i] == '#') break;
            std::size_t j = i;
            while (j < line.size() && !blank(line[j])) ++j;
            tok.push_back(line.substr(i, j - i));
            i = j;
        }
        // The statements tinyobjloader reads go to it as checked here, one space apart.
        auto keep = [&] {
            for (std::size_t i = 0; i < tok.size(); ++i) {
                if (i) s.forTinyobj += ' ';
                s.forTinyobj.append(tok[i].data(), tok[i].size());
            }
        };
        const std::string_view key = tok.empty() ? std::string_view() : tok[0];
        const std::size_t n = tok.empty() ? 0 : tok.size() - 1;
        if (tok.empty()) {
            // blank or comment
        } else if (key == "v") {
            // x y z, optionally w (a rational weight, meaningless here) or r g b (vertex
            // colours, which tinyobjloader reads).
            if (n != 3 && n != 4 && n != 6)
                at.fail("vertex needs 3 coordinates (x y z, optionally w or r g b), not " + std::to_string(n));
            for (std::size_t i = 1; i <= n; ++i) {
                const double x = objReal(at, tok[i], "vertex coordinate");
                if (i <= 3) s.positions.push_back(x);
            }
            ++nv;
            keep();
        } else if (key == "vt") {
            if (n != 2 && n != 3) at.fail("texture coordinate needs 2 numbers (u v, optionally w), not " + std::to_string(n));
            for (std::size_t i = 1; i <= n; ++i) {
                const double x = objReal(at, tok[i], "texture coordinate");
                if (i <= 2) s.uvs.push_back(x);
            }
            ++nvt;
            keep();
        } else if (key == "vn") {
            if (n != 3) at.fail("normal needs 3 numbers, not " + std::to_string(n));
            for (std::size_t i = 1; i <= n; ++i) objReal(at, tok[i], "normal coordinate");
            ++s.normals;
            keep();
        } else if (key == "f") {
            if (n < 3) at.fail("face needs at least 3 vertices, not " + std::to_string(n));
            // tinyobjloader stores face sizes as unsigned char.
            if (n > 255) at.fail("face has " + std::to_string(n) + " vertices; at most 255 are supported");
            const std::size_t first = d.faceVertices.size();
            std::size_t withUV = 0;
            for (std::size_t i = 1; i <= n; ++i) {
                const ObjCorner c = objCorner(at, tok[i], nv, nvt, s.normals);
                for (std::size_t k = first; k < d.faceVertices.size(); ++k)
                    if (d.faceVertices[k] == c.v) at.fail("face uses vertex " + std::to_string(c.v + 1) + " twice");
                d.faceVertices.push_back(c.v);
                d.faceUVs.push_back(c.vt);
                faceNormals.push_back(c.vn);
                if (c.vt >= 0) ++withUV;
            }
            if (withUV != 0 && withUV != n) at.fail("some corners of the face have texture coordinates and some do not");
            if (firstFaceLine == 0) {
                firstFaceLine = at.line;
                firstFaceUV = withUV != 0;
            } else if ((withUV != 0) != firstFaceUV) {
                at.fail(std::string("some faces have texture coordinates and some do not: this face has ") +
                        (firstFaceUV ? "none" : "them") + ", the face at line " + std::to_string(firstFaceLine) +
                        (firstFaceUV ? " has them" : " has none"));
            }
            d.faceSizes.push_back(static_cast<int>(n));
            d.faceMaterials.push_back(material);
            s.faceLines.push_back(at.line);
            keep();
        } else if (key == "l" || key == "p") {
            // Polylines and points are not part of the subdivision surface: checked, then left
            // out.
            if (n < (key == "l" ? 2u : 1u)) at.fail(key == "l" ? "line needs at least 2 vertices" : "point needs a vertex");
            for (std::size_t i = 1; i <= n; ++i) ignored.push_back({at.line, objCorner(at, tok[i], nv, nvt, s.normals)});
        } else if (key == "t") {
            objTag(at, tok, s, optionLines);
        } else if (key == "usemtl") {
            // The faces that follow carry this material: the rest of the line, its words
            // joined by one space (tinyobjloader keeps the first word only; exporters write
            // names with spaces); no name: no material. The .mtl file is never read.
            std::string mat;
            for (std::size_t i = 1; i <= n; ++i) (mat += i > 1 ? " " : "") += tok[i];
            if (mat.empty()) {
                material = -1;
            } else {
                const auto [it, added] = materialIndex.emplace(mat, static_cast<int>(d.materials.size()));
                if (added) d.materials.push_back(std::move(mat));
                material = it->second;
            }
        } else if (key == "o" || key == "g" || key == "s" || key == "mg" || key == "mtllib" ||
                   key == "usemap" || key == "maplib" || key == "lod" || key == "bevel" || key == "c_interp" ||
                   key == "d_interp" || key == "shadow_obj" || key == "trace_obj") {
            // Names, groups, smoothing groups, materials, display attributes: nothing of the
            // surface.
        } else {
            // Free-form curves and surfaces (vp, cstype, curv, surf, ...), tinyobjloader's
            // extensions (vw) and anything else: refused rather than dropped.
            at.fail("unknown or unsupported OBJ statement " + objQuote(key));
        }
        s.forTinyobj += '\n';
    }

    // Positive indices may refer forward: their range is known now.
    auto rangeCheck = [&](const ObjCorner& c) {
        if (c.v >= nv)
            at.fail("refers to vertex " + std::to_string(c.v + 1) + ", but the file has " + std::to_string(nv) + " vertices");
        if (c.vt >= nvt)
            at.fail("refers to texture coordinate " + std::to_string(c.vt + 1) + ", but the file has " + std::to_string(nvt));
        if (c.vn >= s.normals)
            at.fail("refers to normal " + std::to_string(c.vn + 1) + ", but the file has " + std::to_string(s.normals));
    };
    for (std::size_t f = 0, k = 0; f < d.faceSizes.size(); ++f) {
        at.line = s.faceLines[f];
        for (int j = 0; j < d.faceSizes[f]; ++j, ++k) rangeCheck({d.faceVertices[k], d.faceUVs[k], faceNormals[k]});
    }
    for (const Reference& r : ignored) {
        at.line = r.line;
        rangeCheck(r.c);
    }
    // Tags (0-based indices).
    const int nf = static_cast<int>(d.faceSizes.size());
    for (std::size_t i = 0; i < d.creaseWeights.size(); ++i) {
        at.line = s.creaseLines[i];
        for (int v : {d.creaseVertexPairs[2 * i], d.creaseVertexPairs[2 * i + 1]})
            if (v < 0 || v >= nv)
                at.fail("crease refers to vertex " + std::to_string(v) + " (0-based), but the mesh has " + std::to_string(nv) +
                        " vertices");
    }
    if (const long i = firstCreaseNotEdge(d); i >= 0) {
        at.line = s.creaseLines[static_cast<std::size_t>(i)];
        at.fail(creaseNotEdge(d, static_cast<std::size_t>(i)));
    }
    for (std::size_t i = 0; i < d.cornerVertices.size(); ++i) {
        at.line = s.cornerLines[i];
        const int v = d.cornerVertices[i];
        if (v < 0 || v >= nv)
            at.fail("corner refers to vertex " + std::to_string(v) + " (0-based), but the mesh has " + std::to_string(nv) +
                    " vertices");
    }
    for (std::size_t i = 0; i < d.holes.size(); ++i) {
        at.line = s.holeLines[i];
        if (d.holes[i] < 0 || d.holes[i] >= nf)
            at.fail("hole refers to face " + std::to_string(d.holes[i]) + " (0-based), but the mesh has " + std::to_string(nf) +
                    " faces");
    }
    if (!firstFaceUV) d.faceUVs.clear();
    if (d.materials.empty()) d.faceMaterials.clear();
    return s;
}

} // namespace detail

/// Parses OBJ text (OpenSubdiv's regression-shape dialect: `t crease`, `corner`, `hole`,
/// `interpolateboundary`, `creasemethod`, `smoothtriangles`, `facevaryinginterpolateboundary`
/// tags). Every line is checked first (detail::scanObj), tinyobjloader then reads the
/// vertices, texture coordinates and faces, and the two readings must agree. The tags are read
/// by the scan only: tinyobjloader keeps at most 8192 values of a tag and loses the tags that
/// follow a `g` or `o` after the last face. The scan also keeps each face's `usemtl` name
/// (MeshDescription::materials; the .mtl file is not read). Throws MeshError
/// "name:line: reason" for anything it does not read completely: binary bytes, malformed or
/// non-finite numbers, faces with fewer than 3 vertices, indices that are 0, not integers or
/// out of range, tags whose counts do not match their values, unknown tags and statements.
inline MeshDescription parseObj(const std::string& text, const std::string& name) {
    detail::ObjScan s = detail::scanObj(text, name);
    tinyobj::ObjReaderConfig config;
    config.triangulate = false;
    config.vertex_color = false;
    config.mtl_search_path = "";
    tinyobj::ObjReader reader;
    if (!reader.ParseFromString(s.forTinyobj, "", config) || !reader.Valid())
        throw MeshError(name + ": not a readable OBJ mesh: " + reader.Error());
    const tinyobj::attrib_t& attrib = reader.GetAttrib();
    MeshDescription d = std::move(s.d);
    // The two readings agree (a disagreement would be a bug of the scan above, not of the file).
    auto disagree = [&](const std::string& what) {
        return MeshError(name + ": the OBJ reader and dispmap's line check disagree on " + what);
    };
    auto same = [](double a, double b) {
        return std::abs(a - b) <= 1e-6 * std::max(std::abs(a), std::abs(b)) + 1e-37;
    };
    if (attrib.vertices.size() != s.positions.size()) throw disagree("the number of vertices");
    if (attrib.texcoords.size() != s.uvs.size()) throw disagree("the number of texture coordinates");
    for (std::size_t i = 0; i < s.positions.size(); ++i)
        if (!same(static_cast<double>(attrib.vertices[i]), s.positions[i])) throw disagree("vertex " + std::to_string(i / 3 + 1));
    for (std::size_t i = 0; i < s.uvs.size(); ++i)
        if (!same(static_cast<double>(attrib.texcoords[i]), s.uvs[i]))
            throw disagree("texture coordinate " + std::to_string(i / 2 + 1));
    std::size_t face = 0, corner = 0;
    for (const tinyobj::shape_t& shape : reader.GetShapes()) {
        std::size_t at = 0;
        for (unsigned char n : shape.mesh.num_face_vertices) {
            if (face >= d.faceSizes.size() || n != d.faceSizes[face]) throw disagree("face " + std::to_string(face + 1));
            for (unsigned char j = 0; j < n; ++j, ++at, ++corner) {
                const tinyobj::index_t& ix = shape.mesh.indices[at];
                if (ix.vertex_index != d.faceVertices[corner] ||
                    (!d.faceUVs.empty() && ix.texcoord_index != d.faceUVs[corner]))
                    throw disagree("face " + std::to_string(face + 1));
            }
            ++face;
        }
    }
    if (face != d.faceSizes.size()) throw disagree("the number of faces");
    // The values are the line check's: std::from_chars rounds correctly, tinyobjloader's own
    // parser can be an ulp off, and a mesh written with shortest round-trip numbers
    // (writeObj) must read back bit for bit.
    for (std::size_t i = 0; i + 2 < s.positions.size(); i += 3)
        d.positions.emplace_back(s.positions[i], s.positions[i + 1], s.positions[i + 2]);
    for (std::size_t i = 0; i + 1 < s.uvs.size(); i += 2)
        d.uvs.emplace_back(s.uvs[i], s.uvs[i + 1]);
    if (d.faceUVs.empty()) d.uvs.clear();
    return d;
}

/// The polygons of an OBJ file fanned into triangles (vertex indices into `positions`): what a
/// voxeliser or a ray caster needs (meso/solid.h's mesoSolidFromMesh). FileError / MeshError
/// for a file that cannot be read or parsed.
struct TriangleSoup {
    std::vector<glm::dvec3> positions;
    std::vector<std::array<int, 3>> triangles;
    std::size_t polygons = 0; ///< faces in the file
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
    out.polygons = m.faceSizes.size();
    return out;
}

/// A validated control mesh with its OpenSubdiv topology.
class ControlMesh {
  public:
    /// Validates `d` and builds the topology. Throws MeshError naming the mesh and the
    /// offending face, vertex or edge: empty mesh, faces with fewer than 3 vertices, indices
    /// out of range, a face using a vertex twice, NaN/Inf positions or weights, crease pairs
    /// that are not edges, arrays of inconsistent sizes, valences beyond OpenSubdiv's limit,
    /// non-manifold edges or vertices.
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
    /// refines adaptively; the one above stays at the base level). With `uvRule` (a mesh with
    /// texture coordinates only) it carries the texture coordinates as face-varying channel 0,
    /// interpolated by that rule (surface/uv_map.h).
    std::unique_ptr<Far::TopologyRefiner> createRefiner(
        std::optional<Sdc::Options::FVarLinearInterpolation> uvRule = std::nullopt) const;
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
    if (!d.faceUVs.empty() && d.faceUVs.size() != d.faceVertices.size())
        throw MeshError(n + ": " + std::to_string(d.faceUVs.size()) + " face texture coordinates for " +
                        std::to_string(d.faceVertices.size()) + " face vertices");
    if (d.creaseVertexPairs.size() != 2 * d.creaseWeights.size())
        throw MeshError(n + ": " + std::to_string(d.creaseVertexPairs.size()) + " crease vertices for " +
                        std::to_string(d.creaseWeights.size()) + " crease sharpness values (two each)");
    if (d.cornerVertices.size() != d.cornerWeights.size())
        throw MeshError(n + ": " + std::to_string(d.cornerVertices.size()) + " corner vertices for " +
                        std::to_string(d.cornerWeights.size()) + " corner sharpness values");
    // OpenSubdiv refuses (with a message to its process-wide callback) faces and vertices of
    // valence above Vtr::VALENCE_LIMIT; a vertex has at most two edges per incident face.
    constexpr int valenceLimit = OpenSubdiv::Vtr::VALENCE_LIMIT;
    std::vector<int> incident(d.positions.size(), 0);
    int at = 0;
    for (std::size_t f = 0; f < d.faceSizes.size(); ++f) {
        const int size = d.faceSizes[f];
        offsets_.push_back(at);
        if (size < 3) throw MeshError(n + ": face " + std::to_string(f + 1) + " has fewer than 3 vertices");
        if (size > valenceLimit)
            throw MeshError(n + ": face " + std::to_string(f + 1) + " has " + std::to_string(size) + " vertices, more than " +
                            std::to_string(valenceLimit));
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
            if (++incident[static_cast<std::size_t>(v)] > valenceLimit / 2)
                throw MeshError(n + ": vertex " + std::to_string(v + 1) + " is in more than " + std::to_string(valenceLimit / 2) +
                                " faces");
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
    // Far warns about, and skips, a crease pair that is not an edge.
    if (const long i = detail::firstCreaseNotEdge(d); i >= 0)
        throw MeshError(n + ": " + detail::creaseNotEdge(d, static_cast<std::size_t>(i)));
    for (int v : d.cornerVertices)
        if (v < 0 || v >= nv) throw MeshError(n + ": corner refers to vertex " + std::to_string(v) + " (0-based), out of range");
    for (int f : d.holes)
        if (f < 0 || f >= static_cast<int>(d.faceSizes.size())) throw MeshError(n + ": hole refers to a missing face");
    for (float w : d.creaseWeights)
        if (!std::isfinite(w) || w < 0.0f) throw MeshError(n + ": crease sharpness must be finite and >= 0");
    for (float w : d.cornerWeights)
        if (!std::isfinite(w) || w < 0.0f) throw MeshError(n + ": corner sharpness must be finite and >= 0");
    if (!d.faceMaterials.empty() && d.faceMaterials.size() != d.faceSizes.size())
        throw MeshError(n + ": " + std::to_string(d.faceMaterials.size()) + " face materials for " + std::to_string(d.faceSizes.size()) +
                        " faces");
    for (int m : d.faceMaterials)
        if (m < -1 || m >= static_cast<int>(d.materials.size()))
            throw MeshError(n + ": a face's material " + std::to_string(m) + " is not one of the " + std::to_string(d.materials.size()) +
                            " materials (-1: none)");

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

inline std::unique_ptr<Far::TopologyRefiner> ControlMesh::createRefiner(
    std::optional<Sdc::Options::FVarLinearInterpolation> uvRule) const {
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
    sdc.SetTriangleSubdivision(d.triangles);
    sdc.SetFVarLinearInterpolation(uvRule.value_or(d.fvarLinear));
    Far::TopologyDescriptor::FVarChannel uvChannel;
    if (uvRule && hasUVs()) {
        uvChannel.numValues = static_cast<int>(d.uvs.size());
        uvChannel.valueIndices = d.faceUVs.data();
        td.numFVarChannels = 1;
        td.fvarChannels = &uvChannel;
    }
    // OpenSubdiv reports errors through one process-wide callback (Far::SetErrorCallback) that
    // belongs to the application: dispmap never sets it. build() has rejected every input Far
    // is known to refuse or warn about, so a failure here is unexpected; Far's own message
    // went to that callback (or to stdout when none is set).
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

/// Writes the control mesh `d` as OBJ (v, f; 1-based; shortest round-trip decimal doubles),
/// atomically: what parseObj reads back with the same positions and face order, hence the same
/// topologyHash. Boundary rule, creases, corners, holes and the non-default rules are written as
/// OpenSubdiv's `t` tags; texture coordinates and materials are not written. Throws FileError naming the path.
inline void writeObj(const MeshDescription& d, const std::string& path) {
    std::string name = d.name; // one comment line, whatever the name holds
    std::replace_if(name.begin(), name.end(), [](char c) { return c == '\n' || c == '\r'; }, ' ');
    std::string s = "# " + name + ": " + std::to_string(d.positions.size()) + " vertices, " +
                    std::to_string(d.faceSizes.size()) + " faces\n";
    for (const glm::dvec3& p : d.positions) {
        s += "v";
        for (int c = 0; c < 3; ++c) {
            s += ' ';
            detail::appendNumber(s, p[c]);
        }
        s += '\n';
    }
    std::size_t at = 0;
    for (int n : d.faceSizes) {
        s += 'f';
        for (int k = 0; k < n; ++k) s += ' ' + std::to_string(d.faceVertices[at++] + 1);
        s += '\n';
    }
    if (d.boundary == Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER) s += "t interpolateboundary 1/0/0 1\n";
    else if (d.boundary == Sdc::Options::VTX_BOUNDARY_NONE) s += "t interpolateboundary 1/0/0 0\n";
    for (std::size_t i = 0; i < d.creaseWeights.size(); ++i) {
        s += "t crease 2/1/0 " + std::to_string(d.creaseVertexPairs[2 * i]) + ' ' + std::to_string(d.creaseVertexPairs[2 * i + 1]) + ' ';
        detail::appendNumber(s, static_cast<double>(d.creaseWeights[i]));
        s += '\n';
    }
    for (std::size_t i = 0; i < d.cornerWeights.size(); ++i) {
        s += "t corner 1/1/0 " + std::to_string(d.cornerVertices[i]) + ' ';
        detail::appendNumber(s, static_cast<double>(d.cornerWeights[i]));
        s += '\n';
    }
    for (int h : d.holes) s += "t hole 1/0/0 " + std::to_string(h) + '\n';
    if (d.creasing == Sdc::Options::CREASE_CHAIKIN) s += "t creasemethod 0/0/1 chaikin\n";
    if (d.triangles == Sdc::Options::TRI_SUB_SMOOTH) s += "t smoothtriangles 0/0/1 smooth\n";
    detail::writeFileAtomically(path, std::vector<unsigned char>(s.begin(), s.end()), "OBJ mesh");
}

} // namespace dispmap
