#pragma once
// Errors of dispmap. Every host function that cannot meet its contract throws one of these,
// with a message that names the input (file, face, vertex, value); none returns NaN or a
// partial result. Kernels have no error path: their callers validate.
#include <stdexcept>
#include <cstddef>
#include <string>
#include <string_view>

namespace dispmap {
class Error : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};
/// A malformed, non-manifold or unsupported control mesh.
class MeshError : public Error {
  public:
    using Error::Error;
};
/// A file that cannot be read or written, or whose content is malformed or corrupted.
class FileError : public Error {
  public:
    using Error::Error;
};
/// An argument out of its documented range (tile size, NaN/Inf data, mismatched sizes).
class ArgumentError : public Error {
  public:
    using Error::Error;
};
namespace detail {
/// A piece of the input (a key, a value, a name) for an error message: at most `max` bytes,
/// cut before a UTF-8 continuation byte and marked "..." where it was cut.
inline std::string excerpt(std::string_view text, std::size_t max = 80) {
    if (text.size() <= max) return std::string(text);
    std::size_t n = max > 3 ? max - 3 : 0;
    while (n > 0 && (static_cast<unsigned char>(text[n]) & 0xC0) == 0x80) --n; // not inside a UTF-8 character
    return std::string(text.substr(0, n)) + "...";
}
} // namespace detail
} // namespace dispmap
