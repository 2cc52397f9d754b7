// Reading point sets from the files people keep them in (NumPy .npy, CSV/text, raw
// float32), and writing .npy for tests and benchmarks. Every reader here treats its input
// as untrusted: sizes are checked against the limits and the file's length before anything
// is allocated, and nothing is read past the end.
#ifndef MLCLUST_CORE_IO_POINTS_IO_H_
#define MLCLUST_CORE_IO_POINTS_IO_H_

#include <cstdint>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "core/points/points.h"

namespace mlclust {

struct PointReadOptions {
  // Dimensions per point (the CLI's --dims). Required for raw float32 files, which do not
  // record it; for every other format 0 means "take it from the file", and a non-zero
  // value is checked against the file (INVALID_ARGUMENT if they differ).
  uint32_t dims = 0;
  // Checked before allocating (d, and m x d against the shape a header declares or the
  // file's size), and by ValidatePoints on the result.
  PointLimits limits;
};

// Reads a point set; the format is chosen by the extension, case-insensitively:
//
//   .npy          NumPy format 1.0, 2.0 or 3.0; dtype float32 or float64 (either byte
//                 order; float64 is rounded to float32, and a finite value beyond float32's
//                 range is refused); shape (m, d); C order, or Fortran order (transposed
//                 while reading). The header must be a dict of exactly 'descr',
//                 'fortran_order' and 'shape', and the file must end where the data does.
//   .csv .txt     one point per line; fields separated by commas if the first non-empty
//                 line has a comma, otherwise by runs of spaces/tabs; fields may be padded
//                 with spaces. Empty lines are skipped, as is the first non-empty line when
//                 none of its fields is a number (a header, e.g. "x,y,z" or NumPy's
//                 "# x y z"). Every data line must have as many fields as the first one.
//                 A leading UTF-8 byte-order mark and CRLF line ends are accepted. Numbers
//                 are parsed with from_chars (correctly rounded, locale-independent); a
//                 leading '+' is allowed; values too small for float32 become 0.
//   .f32 .bin .raw  bare float32 little-endian, row-major; needs options.dims.
//
// Errors, each naming the file and, for text, the 1-based line ("row") and field
// ("column") of the file:
//   NOT_FOUND            the file does not exist;
//   INVALID_ARGUMENT     unknown extension; anything malformed: bad magic, unsupported
//                        version, a header that is not the expected dict, a dtype other
//                        than float32/float64, a shape that is not 2-D, a truncated file
//                        (expected and actual byte counts) or trailing bytes, a non-numeric
//                        field, a row with a different field count (both counts), a NaN or
//                        infinite value, a raw file without dims or whose size is not a
//                        whole number of points; d or m x d over options.limits; and
//                        whatever ValidatePoints refuses, which every result passes;
//   the errno-derived code (e.g. PERMISSION_DENIED) if the file cannot be read.
absl::StatusOr<PointSet> ReadPointsFile(const std::string& path,
                                        const PointReadOptions& options = {});

// The .npy and text decoders of ReadPointsFile, on bytes already in memory (a fuzz target
// and the way in for bytes that did not come from a file). Same rules and errors, without
// the file name in the messages.
absl::StatusOr<PointSet> DecodePointsNpy(absl::string_view bytes,
                                         const PointReadOptions& options = {});
absl::StatusOr<PointSet> DecodePointsText(absl::string_view text,
                                          const PointReadOptions& options = {});

// Writes `points` as a NumPy 1.0 file: dtype '<f4', C order, shape (m, d), header padded
// to 64 bytes as NumPy does. Values are written as they are (NaN included), so that tests
// can build bad files; m = 0 is allowed. INVALID_ARGUMENT if dims is 0 or values is not a
// whole number of points; the errno-derived code if the file cannot be written.
absl::Status WritePointsNpy(const std::string& path, const PointSet& points);

}  // namespace mlclust

#endif  // MLCLUST_CORE_IO_POINTS_IO_H_
