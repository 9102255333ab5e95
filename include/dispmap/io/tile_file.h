#pragma once
// The tile file: a TileSet on disk, bit for bit (saveTiles / loadTiles). Needs zlib (crc32).
//
// Format, version 1. Every integer is little-endian and written byte by byte, so the code
// does not depend on the host's byte order; floats are IEEE-754 binary32, stored as the
// little-endian bytes of their bit pattern (no conversion, no formatting).
//
//   offset        size      field
//   0             8         magic "DMTILES\0"
//   8             4         u32 version = 1
//   12            4         u32 H, the header byte count (13 in version 1; a reader skips
//                           bytes beyond the fields it knows, reserved for compatible additions)
//   16            1         u8  mip filter (0 = Haar, 1 = BWavelet)
//   17            4         u32 tile count N
//   21            8         u64 topology hash
//   16 + H        5 N       per tile: u8 k (kMinTileLog2..kMaxTileLog2), u8[4] sizeDifferences
//                           (each <= k - kMinTileLog2)
//   16 + H + 5 N  4 C       f32 coefficients: tile 0's levels finest first, then tile 1, ...;
//                           Tile::totalTexels(k) per tile, C the sum over the tiles
//   size - 4      4         u32 CRC-32 (zlib crc32) of every byte before it
//
// Nothing may follow the checksum. A loaded file has passed: size checks before every read,
// magic, version, header size, filter, k and size-difference ranges, total size, checksum,
// and finiteness of every coefficient. Failures are FileError; invalid data given to
// saveTiles is ArgumentError. Writes are atomic (temporary file in the same directory, then
// rename): a failed save leaves an existing file untouched and no temporary behind.
#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <system_error>
#include <vector>

#include <zlib.h>

#include "dispmap/core/error.h"
#include "dispmap/core/file_io.h"
#include "dispmap/core/tileset.h"

namespace dispmap {

namespace detail {

// zlib's CRC-32 of n bytes (fed in chunks, as zlib takes 32-bit lengths).
inline std::uint32_t crc32Of(const unsigned char* data, std::size_t n) {
    uLong crc = crc32(0L, nullptr, 0);
    while (n > 0) {
        const std::size_t chunk = std::min<std::size_t>(n, std::size_t{1} << 30);
        crc = crc32(crc, data, static_cast<uInt>(chunk));
        data += chunk;
        n -= chunk;
    }
    return static_cast<std::uint32_t>(crc);
}

inline constexpr std::array<unsigned char, 8> kTileFileMagic = {'D', 'M', 'T', 'I', 'L', 'E', 'S', '\0'};
inline constexpr std::uint32_t kTileFileVersion = 1;
inline constexpr std::uint32_t kTileFileHeaderBytes = 1 + 4 + 8; // filter, tile count, topology hash
inline constexpr std::size_t kTileFileRecordBytes = 5;           // k, sizeDifferences[4]
/// Largest tile file read (or written): the renderers upload the coefficients as one storage
/// buffer, and a Vulkan device addresses at most 4 GiB in one (maxStorageBufferRange is 32-bit).
inline constexpr std::uint64_t kMaxTileFileBytes = std::uint64_t{4} << 30;

static_assert(std::numeric_limits<float>::is_iec559 && sizeof(float) == 4,
              "the tile file stores IEEE-754 binary32 floats");

// Why a tile's k and size differences cannot be stored, or "" if they can (used by both
// saveTiles and loadTiles, so that every file saveTiles writes loadTiles reads).
inline std::string tileShapeProblem(int k, const std::array<std::uint8_t, 4>& differences) {
    if (k < kMinTileLog2 || k > kMaxTileLog2)
        return "k = " + std::to_string(k) + " is outside [" + std::to_string(kMinTileLog2) + ", " +
               std::to_string(kMaxTileLog2) + "]";
    for (std::size_t c = 0; c < 4; ++c)
        if (differences[c] > k - kMinTileLog2)
            return "size difference " + std::to_string(differences[c]) + " at corner " + std::to_string(c) +
                   " exceeds k - " + std::to_string(kMinTileLog2) + " = " + std::to_string(k - kMinTileLog2);
    return {};
}

// Index of the first NaN or infinite value, or n if all are finite.
inline std::size_t firstNonFinite(const float* v, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i)
        if (!std::isfinite(v[i])) return i;
    return n;
}

// Appends little-endian integers and floats to a byte vector.
struct ByteWriter {
    std::vector<unsigned char> bytes;
    void u8(std::uint8_t v) { bytes.push_back(v); }
    void u32(std::uint32_t v) {
        for (int i = 0; i < 4; ++i)
            bytes.push_back(static_cast<unsigned char>(v >> (8 * i)));
    }
    void u64(std::uint64_t v) {
        for (int i = 0; i < 8; ++i)
            bytes.push_back(static_cast<unsigned char>(v >> (8 * i)));
    }
    void f32(float v) { u32(std::bit_cast<std::uint32_t>(v)); }
};

// Reads little-endian values from a byte vector; every read first checks that the bytes are
// there and throws FileError "<kind> '<path>': truncated at byte <size> (reading <what>)" if not.
struct ByteReader {
    const std::vector<unsigned char>& bytes;
    const std::string& path;
    std::size_t pos = 0;
    const char* kind = "tile file"; ///< what the file is, in messages ("mesostructure file")

    std::size_t remaining() const { return bytes.size() - pos; }
    void require(std::uint64_t n, const char* what) const {
        if (n > remaining())
            throw FileError(std::string(kind) + " '" + path + "': truncated at byte " + std::to_string(bytes.size()) +
                            " (reading " + what + ")");
    }
    void skip(std::uint64_t n, const char* what) {
        require(n, what);
        pos += static_cast<std::size_t>(n);
    }
    std::uint64_t little(int n, const char* what) {
        require(static_cast<std::uint64_t>(n), what);
        std::uint64_t v = 0;
        for (int i = 0; i < n; ++i)
            v |= static_cast<std::uint64_t>(bytes[pos++]) << (8 * i);
        return v;
    }
    std::uint8_t u8(const char* what) { return static_cast<std::uint8_t>(little(1, what)); }
    std::uint32_t u32(const char* what) { return static_cast<std::uint32_t>(little(4, what)); }
    std::uint64_t u64(const char* what) { return little(8, what); }
    float f32(const char* what) { return std::bit_cast<float>(u32(what)); }
};

} // namespace detail

/// The size of the file saveTiles writes for `tiles` tiles holding `floats` coefficients in all:
/// magic, version and header size (16), the header, one record per tile, the coefficients, the CRC.
inline std::uint64_t tileFileBytes(std::uint64_t tiles, std::uint64_t floats) {
    return 16 + detail::kTileFileHeaderBytes + detail::kTileFileRecordBytes * tiles + 4 * floats + 4;
}
inline std::uint64_t tileFileBytes(const TileSet& tiles) {
    std::uint64_t floats = 0;
    for (const Tile& t : tiles.tiles) floats += t.coefficients.size();
    return tileFileBytes(tiles.tiles.size(), floats);
}

/// Writes tiles to path in the tile file format above, atomically. Throws ArgumentError
/// (naming the tile) if a tile has k outside [kMinTileLog2, kMaxTileLog2], a size difference
/// above k - kMinTileLog2, coefficients.size() != Tile::totalTexels(k), a NaN/Inf
/// coefficient or a file above detail::kMaxTileFileBytes (nothing is written then), and FileError if the file cannot be written.
inline void saveTiles(const TileSet& tiles, const std::string& path) {
    const auto invalid = [&](std::size_t i, const std::string& why) {
        return ArgumentError("saveTiles('" + path + "'): tile " + std::to_string(i) + ": " + why);
    };
    if (tiles.tiles.size() > std::numeric_limits<std::uint32_t>::max())
        throw ArgumentError("saveTiles('" + path + "'): " + std::to_string(tiles.tiles.size()) +
                            " tiles exceed the format's 32-bit tile count");
    if (tiles.filter != MipFilter::Haar && tiles.filter != MipFilter::BWavelet)
        throw ArgumentError("saveTiles('" + path + "'): unknown mip filter " +
                            std::to_string(static_cast<int>(tiles.filter)));
    std::size_t floats = 0;
    for (std::size_t i = 0; i < tiles.tiles.size(); ++i) {
        const Tile& t = tiles.tiles[i];
        if (std::string why = detail::tileShapeProblem(t.k, t.sizeDifferences); !why.empty())
            throw invalid(i, why);
        if (t.coefficients.size() != Tile::totalTexels(t.k))
            throw invalid(i, std::to_string(t.coefficients.size()) + " coefficients, k = " +
                                 std::to_string(t.k) + " needs " + std::to_string(Tile::totalTexels(t.k)));
        const std::size_t bad = detail::firstNonFinite(t.coefficients.data(), t.coefficients.size());
        if (bad < t.coefficients.size())
            throw invalid(i, "coefficient " + std::to_string(bad) + " is not finite (" +
                                 std::to_string(t.coefficients[bad]) + ")");
        floats += t.coefficients.size();
    }

    const std::uint64_t fileBytes = tileFileBytes(tiles.tiles.size(), floats);
    if (fileBytes > detail::kMaxTileFileBytes)
        throw ArgumentError("saveTiles('" + path + "'): " + std::to_string(fileBytes) + " bytes are more than the " +
                            std::to_string(detail::kMaxTileFileBytes) + " a tile file may have (loadTiles would refuse it)");
    detail::ByteWriter out;
    out.bytes.reserve(static_cast<std::size_t>(fileBytes));
    out.bytes.insert(out.bytes.end(), detail::kTileFileMagic.begin(), detail::kTileFileMagic.end());
    out.u32(detail::kTileFileVersion);
    out.u32(detail::kTileFileHeaderBytes);
    out.u8(static_cast<std::uint8_t>(tiles.filter));
    out.u32(static_cast<std::uint32_t>(tiles.tiles.size()));
    out.u64(tiles.topologyHash);
    for (const Tile& t : tiles.tiles) {
        out.u8(static_cast<std::uint8_t>(t.k));
        for (std::uint8_t d : t.sizeDifferences)
            out.u8(d);
    }
    for (const Tile& t : tiles.tiles)
        for (float c : t.coefficients)
            out.f32(c);
    out.u32(detail::crc32Of(out.bytes.data(), out.bytes.size()));
    detail::writeFileAtomically(path, out.bytes, "tile file");
}

/// Reads a tile file written by saveTiles; the result is bit for bit what was saved. Throws
/// FileError naming path and the reason: cannot open, not a regular file, larger than
/// detail::kMaxTileFileBytes, bad magic, unsupported version,
/// truncated (with the byte offset), invalid header, filter, k or size difference, trailing
/// bytes, checksum mismatch, or a NaN/Inf coefficient.
inline TileSet loadTiles(const std::string& path) {
    const std::vector<unsigned char> bytes = detail::readFileBytes(path, "tile file", detail::kMaxTileFileBytes);
    const auto corrupt = [&](const std::string& why) {
        return FileError("tile file '" + path + "': " + why);
    };
    detail::ByteReader in{bytes, path};

    const std::size_t magicBytes = std::min(bytes.size(), detail::kTileFileMagic.size());
    if (!std::equal(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(magicBytes),
                    detail::kTileFileMagic.begin()))
        throw corrupt("not a dispmap tile file (bad magic)");
    in.skip(detail::kTileFileMagic.size(), "the magic");
    const std::uint32_t version = in.u32("the version");
    if (version != detail::kTileFileVersion)
        throw corrupt("unsupported version " + std::to_string(version) + "; this build supports version " +
                      std::to_string(detail::kTileFileVersion) +
                      (version > detail::kTileFileVersion ? " (the file is from a newer dispmap)" : ""));
    const std::uint32_t headerBytes = in.u32("the header size");
    if (headerBytes < detail::kTileFileHeaderBytes)
        throw corrupt("header size " + std::to_string(headerBytes) + " is below the " +
                      std::to_string(detail::kTileFileHeaderBytes) + " bytes of version 1");
    in.require(headerBytes, "the header");
    TileSet out;
    const std::uint8_t filter = in.u8("the mip filter");
    if (filter > static_cast<std::uint8_t>(MipFilter::BWavelet))
        throw corrupt("unknown mip filter " + std::to_string(filter));
    out.filter = static_cast<MipFilter>(filter);
    const std::uint32_t count = in.u32("the tile count");
    out.topologyHash = in.u64("the topology hash");
    in.skip(headerBytes - detail::kTileFileHeaderBytes, "the header");

    // Checked before allocating, so that a corrupted count cannot ask for gigabytes.
    in.require(std::uint64_t{count} * detail::kTileFileRecordBytes, "the tile table");
    out.tiles.resize(count);
    std::uint64_t floats = 0;
    for (std::size_t i = 0; i < out.tiles.size(); ++i) {
        Tile& t = out.tiles[i];
        t.k = in.u8("the tile table");
        for (std::uint8_t& d : t.sizeDifferences)
            d = in.u8("the tile table");
        if (std::string why = detail::tileShapeProblem(t.k, t.sizeDifferences); !why.empty())
            throw corrupt("tile " + std::to_string(i) + ": " + why);
        floats += Tile::totalTexels(t.k);
    }
    in.require(4 * floats + 4, "the coefficients and checksum");
    if (in.remaining() != 4 * floats + 4)
        throw corrupt(std::to_string(in.remaining() - 4 * floats - 4) +
                      " unexpected bytes after the checksum");

    const std::size_t crcAt = bytes.size() - 4;
    detail::ByteReader crcIn{bytes, path, crcAt};
    const std::uint32_t stored = crcIn.u32("the checksum");
    const std::uint32_t computed = detail::crc32Of(bytes.data(), crcAt);
    if (stored != computed)
        throw corrupt("checksum mismatch (stored " + std::to_string(stored) + ", computed " +
                      std::to_string(computed) + "): the file is corrupted");

    for (std::size_t i = 0; i < out.tiles.size(); ++i) {
        Tile& t = out.tiles[i];
        t.coefficients.resize(Tile::totalTexels(t.k));
        for (float& c : t.coefficients)
            c = in.f32("the coefficients");
        const std::size_t bad = detail::firstNonFinite(t.coefficients.data(), t.coefficients.size());
        if (bad < t.coefficients.size())
            throw corrupt("tile " + std::to_string(i) + ": coefficient " + std::to_string(bad) +
                          " is not finite (" + std::to_string(t.coefficients[bad]) + ")");
    }
    return out;
}

} // namespace dispmap
