#pragma once
// The mesostructure file: a MesoMaps on disk, bit for bit (saveMesoMaps / loadMesoMaps), so
// a tool bakes the maps once and an engine uploads them. Needs zlib (crc32).
//
// Format, version 2; integers little-endian, floats as the bits of IEEE-754 binary32:
//   magic "DMMESO\0\0", u32 version = 2,
//   u32 width, height, layers, u8 cones m, n, shadow, isotropic, u32 block, u32 subsamples,
//   f32 heights[width height], f32 distance[width height layers],
//   u32 grid word count G, u32 words[G], u32 atlas value count A, f32 atlas[A],
//   u32 plane value count P, f32 planes[P] (CompressedDdm::planes; version 1 has neither),
//   f32 quadrics[12 width height], u32 CRC-32 of every byte before it.
// Version 1 files (no plane blocks) still load. A load checks sizes before every read, the
// magic, version, ranges, that G and A are those the sizes imply, that every atlas block and
// plane record a grid word names exists, finiteness, and the checksum;
// failures are FileError naming the file (as a mesostructure file). Files above
// kMaxMesoFileBytes are neither written (ArgumentError) nor read. Writes are atomic.
#include "dispmap/meso/march.h"
#include "dispmap/io/tile_file.h" // ByteWriter, ByteReader, crc32Of

namespace dispmap {

inline constexpr std::array<unsigned char, 8> kMesoFileMagic = {'D', 'M', 'M', 'E', 'S', 'O', '\0', '\0'};
inline constexpr std::uint32_t kMesoFileVersion = 2;
/// Largest mesostructure file read: the renderer uploads each map as one storage buffer, and a
/// Vulkan device addresses at most 4 GiB in one (maxStorageBufferRange is 32-bit).
inline constexpr std::uint64_t kMaxMesoFileBytes = std::uint64_t{4} << 30;

inline void saveMesoMaps(const MesoMaps& m, const std::string& path) {
    if (m.isSolid())
        throw ArgumentError("saveMesoMaps('" + path + "'): the file holds a height field's maps; a solid's (mesh) are built from its mesh");
    const MesoHeightField& f = m.field;
    if (m.distance.d.size() != f.h.size() * static_cast<std::size_t>(f.layers) ||
        m.quadrics.q.size() != 3 * f.h.size() || m.ddm.width != f.width || m.ddm.height != f.height || m.ddm.layers != f.layers ||
        m.ddm.gx * m.ddm.block != f.width || m.ddm.gy * m.ddm.block != f.height || m.ddm.gz * m.ddm.block != f.layers ||
        m.ddm.grid.size() != static_cast<std::size_t>(m.ddm.cones.count()) * static_cast<std::size_t>(m.ddm.gx) *
                                 static_cast<std::size_t>(m.ddm.gy) * static_cast<std::size_t>(m.ddm.gz))
        throw ArgumentError("saveMesoMaps('" + path + "'): the maps do not belong to one height field, or one was not built "
                            "(the file holds all of them)");
    detail::ByteWriter out;
    out.bytes.insert(out.bytes.end(), kMesoFileMagic.begin(), kMesoFileMagic.end());
    out.u32(kMesoFileVersion);
    out.u32(static_cast<std::uint32_t>(f.width));
    out.u32(static_cast<std::uint32_t>(f.height));
    out.u32(static_cast<std::uint32_t>(f.layers));
    out.u8(static_cast<std::uint8_t>(m.ddm.cones.m));
    out.u8(static_cast<std::uint8_t>(m.ddm.cones.n));
    out.u8(m.ddm.cones.shadow ? 1 : 0);
    out.u8(m.ddm.cones.isotropic ? 1 : 0);
    out.u32(static_cast<std::uint32_t>(m.ddm.block));
    out.u32(static_cast<std::uint32_t>(m.distance.subsamples));
    for (float v : f.h) out.f32(v);
    for (float v : m.distance.d) out.f32(v);
    out.u32(static_cast<std::uint32_t>(m.ddm.grid.size()));
    for (std::uint32_t w : m.ddm.grid) out.u32(w);
    out.u32(static_cast<std::uint32_t>(m.ddm.atlas.size()));
    for (float v : m.ddm.atlas) out.f32(v);
    out.u32(static_cast<std::uint32_t>(m.ddm.planes.size()));
    for (float v : m.ddm.planes) out.f32(v);
    for (const glm::vec4& q : m.quadrics.q)
        for (int i = 0; i < 4; ++i) out.f32(q[i]);
    out.u32(detail::crc32Of(out.bytes.data(), out.bytes.size()));
    if (out.bytes.size() > kMaxMesoFileBytes)
        throw ArgumentError("saveMesoMaps('" + path + "'): " + std::to_string(out.bytes.size()) + " bytes are more than the " +
                            std::to_string(kMaxMesoFileBytes) + " a mesostructure file may have (loadMesoMaps would refuse it)");
    detail::writeFileAtomically(path, out.bytes, "mesostructure file");
}

inline MesoMaps loadMesoMaps(const std::string& path) {
    const std::vector<unsigned char> bytes = detail::readFileBytes(path, "mesostructure file", kMaxMesoFileBytes);
    const auto corrupt = [&](const std::string& why) { return FileError("mesostructure file '" + path + "': " + why); };
    if (bytes.size() < kMesoFileMagic.size() + 8 || !std::equal(kMesoFileMagic.begin(), kMesoFileMagic.end(), bytes.begin()))
        throw corrupt("not a mesostructure file (bad magic)");
    const std::size_t crcAt = bytes.size() - 4;
    detail::ByteReader crcIn{bytes, path, crcAt, "mesostructure file"};
    const std::uint32_t stored = crcIn.u32("the checksum");
    if (stored != detail::crc32Of(bytes.data(), crcAt)) throw corrupt("checksum mismatch: the file is corrupted or truncated");
    detail::ByteReader in{bytes, path, kMesoFileMagic.size(), "mesostructure file"};
    const std::uint32_t version = in.u32("the version");
    if (version != 1 && version != kMesoFileVersion) throw corrupt("unsupported version " + std::to_string(version));
    MesoMaps m;
    const auto dim = [&](const char* what, std::uint32_t hi) {
        const std::uint32_t v = in.u32(what);
        if (v < 2 || v > hi) throw corrupt(std::string(what) + " " + std::to_string(v) + " out of range");
        return static_cast<int>(v);
    };
    const int W = dim("width", kMaxMesoSize), H = dim("height", kMaxMesoSize), L = dim("layers", kMaxMesoLayers);
    ConeSet cones;
    cones.m = in.u8("cones");
    cones.n = in.u8("cones");
    cones.shadow = in.u8("cones") != 0;
    cones.isotropic = in.u8("cones") != 0;
    try {
        cones.validate();
    } catch (const ArgumentError& e) {
        throw corrupt(e.what());
    }
    const std::uint32_t block = in.u32("block"), sub = in.u32("subsamples");
    if (block < 1 || block > 32 || W % static_cast<int>(block) || H % static_cast<int>(block) || L % static_cast<int>(block) ||
        sub < 1 || sub > 16)
        throw corrupt("block " + std::to_string(block) + " or subsamples " + std::to_string(sub) + " invalid for the sizes");
    const std::size_t texels = static_cast<std::size_t>(W) * static_cast<std::size_t>(H);
    const auto floats = [&](std::vector<float>& v, std::size_t n, const char* what) {
        in.require(4 * static_cast<std::uint64_t>(n), what);
        v.resize(n);
        for (float& x : v) x = in.f32(what);
        if (detail::firstNonFinite(v.data(), n) < n) throw corrupt(std::string(what) + ": a value is not finite");
    };
    std::vector<float> heights;
    floats(heights, texels, "the heights");
    try {
        m.field = mesoHeightField(W, H, L, std::move(heights));
    } catch (const ArgumentError& e) {
        throw corrupt(e.what());
    }
    m.distance.width = W;
    m.distance.height = H;
    m.distance.layers = L;
    m.distance.subsamples = static_cast<int>(sub);
    floats(m.distance.d, texels * static_cast<std::size_t>(L), "the distance map");
    CompressedDdm& c = m.ddm;
    c.width = W;
    c.height = H;
    c.layers = L;
    c.block = static_cast<int>(block);
    c.cones = cones;
    c.gx = W / c.block;
    c.gy = H / c.block;
    c.gz = L / c.block;
    const std::size_t words = static_cast<std::size_t>(cones.count()) * static_cast<std::size_t>(c.gx) * static_cast<std::size_t>(c.gy) *
                              static_cast<std::size_t>(c.gz);
    if (in.u32("the grid size") != words) throw corrupt("grid size does not match the sizes and cones");
    in.require(4 * static_cast<std::uint64_t>(words), "the grid");
    c.grid.resize(words);
    for (std::uint32_t& w : c.grid) w = in.u32("the grid");
    const std::uint32_t atlasValues = in.u32("the atlas size");
    const std::size_t blockValues = static_cast<std::size_t>(block * block * block);
    if (atlasValues % blockValues) throw corrupt("atlas size is not a whole number of blocks");
    floats(c.atlas, atlasValues, "the atlas");
    if (version >= 2) {
        const std::uint32_t planeValues = in.u32("the plane count");
        if (planeValues % 4) throw corrupt("plane values are not a whole number of planes");
        floats(c.planes, planeValues, "the planes");
    }
    if (!c.wordsValid()) throw corrupt("a grid word names a missing atlas block or plane, or holds a bad distance");
    std::vector<float> q;
    floats(q, 12 * texels, "the quadrics");
    m.quadrics.width = W;
    m.quadrics.height = H;
    m.quadrics.q.resize(3 * texels);
    for (std::size_t i = 0; i < m.quadrics.q.size(); ++i) m.quadrics.q[i] = {q[4 * i], q[4 * i + 1], q[4 * i + 2], q[4 * i + 3]};
    // The reader spans the checksum too: maps that reach into it are short by those bytes.
    if (in.remaining() < 4) throw corrupt("truncated: the maps run into the checksum");
    if (in.remaining() != 4) throw corrupt(std::to_string(in.remaining() - 4) + " unexpected bytes before the checksum");
    m.denseDdmBytes = c.uncompressedBytes();
    return m;
}

} // namespace dispmap
