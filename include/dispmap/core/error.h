#pragma once
// Errors of dispmap. Every host function that cannot meet its contract throws one of these,
// with a message that names the input (file, face, vertex, value); none returns NaN or a
// partial result. Kernels have no error path: their callers validate.
#include <stdexcept>
#include <string>

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
} // namespace dispmap
