#include "core/io/points_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cassert>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/charconv.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/base/status_macros.h"

namespace mlclust {
namespace {

constexpr absl::string_view kNpyMagic("\x93NUMPY", 6);

// A value quoted from untrusted input for a message, cut short: printable ASCII as it is
// (so that a header's quotes read as written), every other byte as \xNN.
std::string Quote(absl::string_view text, size_t max_chars = 40) {
  std::string out = "'";
  for (size_t i = 0; i < std::min(text.size(), max_chars); ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7f) {
      out.push_back(static_cast<char>(c));
    } else {
      absl::StrAppend(&out, "\\x", absl::Hex(c, absl::kZeroPad2));
    }
  }
  absl::StrAppend(&out, text.size() > max_chars ? "...'" : "'");
  return out;
}

// ---------------------------------------------------------------------------------------
// Where bytes come from. The .npy and raw readers check a file's declared size against
// its real length before allocating, then read the data straight into the result; the
// same code runs on bytes in memory (DecodePointsNpy, the fuzz target).

class ByteSource {
 public:
  virtual ~ByteSource() = default;
  virtual uint64_t size() const = 0;
  // Copies bytes [offset, offset + length) to `out`. The caller has checked that they lie
  // within size(); a file that shrank meanwhile is reported, not read past.
  virtual absl::Status ReadAt(uint64_t offset, size_t length, void* out) = 0;
};

class MemorySource final : public ByteSource {
 public:
  explicit MemorySource(absl::string_view bytes) : bytes_(bytes) {}
  uint64_t size() const override { return bytes_.size(); }
  absl::Status ReadAt(uint64_t offset, size_t length, void* out) override {
    assert(offset <= bytes_.size() && length <= bytes_.size() - offset);
    if (length > 0) std::memcpy(out, bytes_.data() + offset, length);
    return absl::OkStatus();
  }

 private:
  absl::string_view bytes_;
};

// Messages here do not name the file: ReadPointsFile puts the path in front of every one.
absl::Status ErrnoError(int error_number, absl::string_view what) {
  // errno 0 would map to OK; a failure with no reason recorded is still a failure.
  const absl::StatusCode code =
      error_number == 0 ? absl::StatusCode::kUnknown : absl::ErrnoToStatusCode(error_number);
  return absl::Status(code, absl::StrCat(what, ": ", std::strerror(error_number)));
}

class FileSource final : public ByteSource {
 public:
  // NOT_FOUND for a missing file, INVALID_ARGUMENT for a directory, FIFO or device.
  static absl::StatusOr<std::unique_ptr<FileSource>> Open(const std::string& path) {
    // O_NONBLOCK so that opening a FIFO cannot hang; it means nothing for a regular file.
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0) {
      if (errno == ENOENT) return absl::NotFoundError("no such file");
      return ErrnoError(errno, "cannot open");
    }
    std::unique_ptr<FileSource> source(new FileSource(fd));
    struct stat info;
    if (::fstat(fd, &info) != 0) return ErrnoError(errno, "cannot inspect");
    if (!S_ISREG(info.st_mode)) return absl::InvalidArgumentError("not a regular file");
    source->size_ = static_cast<uint64_t>(info.st_size);
    return source;
  }
  ~FileSource() override { ::close(fd_); }
  FileSource(const FileSource&) = delete;
  FileSource& operator=(const FileSource&) = delete;

  uint64_t size() const override { return size_; }
  absl::Status ReadAt(uint64_t offset, size_t length, void* out) override {
    char* at = static_cast<char*>(out);
    while (length > 0) {
      const ssize_t got =
          ::pread(fd_, at, std::min<size_t>(length, size_t{1} << 30), static_cast<off_t>(offset));
      if (got < 0) {
        if (errno == EINTR) continue;
        return ErrnoError(errno, "read failed");
      }
      if (got == 0) {
        return absl::InvalidArgumentError(absl::StrCat(
            "ended at byte ", offset, " while reading; it was ", size_, " bytes when opened"));
      }
      at += got;
      offset += static_cast<uint64_t>(got);
      length -= static_cast<size_t>(got);
    }
    return absl::OkStatus();
  }

 private:
  explicit FileSource(int fd) : fd_(fd) {}
  int fd_;
  uint64_t size_ = 0;
};

// ---------------------------------------------------------------------------------------
// Checks shared by the readers.

// The limits on d and m x d, checked before anything of that size is allocated. The
// wording follows ValidatePoints, which checks the result again.
absl::Status CheckShapeWithinLimits(uint64_t m, uint64_t d, const PointLimits& limits) {
  if (d > limits.max_dims) {
    return absl::InvalidArgumentError(
        absl::StrCat("points: d = ", d, " dimensions is over the limit of ", limits.max_dims));
  }
  uint64_t values = 0;
  if (__builtin_mul_overflow(m, d, &values) || values > limits.max_values) {
    return absl::InvalidArgumentError(absl::StrCat(
        "points: m x d = ", m, " x ", d, " values is over the limit of ", limits.max_values));
  }
  return absl::OkStatus();
}

absl::StatusOr<PointSet> Finish(PointSet points, const PointReadOptions& options) {
  if (options.dims != 0 && points.dims != options.dims) {
    return absl::InvalidArgumentError(absl::StrCat("the points have d = ", points.dims,
                                                   " dimensions but --dims ", options.dims,
                                                   " was given"));
  }
  MLCLUST_RETURN_IF_ERROR(ValidatePoints(points, options.limits));
  return points;
}

uint32_t LoadLittleEndian32(const unsigned char* bytes) {
  return uint32_t{bytes[0]} | uint32_t{bytes[1]} << 8 | uint32_t{bytes[2]} << 16 |
         uint32_t{bytes[3]} << 24;
}

// ---------------------------------------------------------------------------------------
// NumPy .npy (https://numpy.org/doc/stable/reference/generated/numpy.lib.format.html):
// the magic "\x93NUMPY", a major and a minor version byte, the header length (uint16
// little-endian in 1.0, uint32 in 2.0 and 3.0), then the header: the repr of a Python dict
// {'descr': '<f4', 'fortran_order': False, 'shape': (m, d), } padded with spaces and ended
// by '\n' (3.0 only allows UTF-8 where 2.0 has Latin-1; with the dtypes read here both are
// ASCII). The data follows the header immediately.

// Header lengths NumPy writes for our dtypes are under 128 bytes; this bounds what a
// hostile 2.0 header can make us allocate and scan.
constexpr uint64_t kMaxNpyHeaderBytes = 64 * 1024;
// NumPy 2 allows 64 dimensions; more is not a NumPy file.
constexpr size_t kMaxNpyRank = 64;

struct NpyHeader {
  std::string descr;
  bool fortran_order = false;
  std::vector<uint64_t> shape;
};

std::string ShapeString(const std::vector<uint64_t>& shape) {
  // As Python prints a tuple: (), (10,), (2, 3).
  return absl::StrCat("(", absl::StrJoin(shape, ", "), shape.size() == 1 ? ",)" : ")");
}

// A strict parser for the one Python literal a .npy header holds. It accepts what
// ast.literal_eval would give NumPy as a valid header for our dtypes (any key order,
// either quote, a trailing comma, whitespace between tokens) and refuses the rest, naming
// the byte where it stopped. Refused although Python takes them: string escapes and
// prefixes, digit separators, line continuations, duplicate keys (Python keeps the last).
class NpyHeaderParser {
 public:
  explicit NpyHeaderParser(absl::string_view text) : text_(text) {}

  absl::StatusOr<NpyHeader> Parse() {
    NpyHeader header;
    bool has_descr = false, has_fortran_order = false, has_shape = false;
    SkipSpace();
    if (!Consume('{')) return Error("expected '{'");
    SkipSpace();
    while (!Consume('}')) {
      std::string key;
      MLCLUST_RETURN_IF_ERROR(ParseString(&key));
      SkipSpace();
      if (!Consume(':')) return Error("expected ':'");
      SkipSpace();
      bool* seen = nullptr;
      if (key == "descr") {
        seen = &has_descr;
        if (Peek() == '[' || Peek() == '{') {
          return absl::InvalidArgumentError(
              "dtype is structured (a list or dict of fields), not float32 or float64");
        }
        MLCLUST_RETURN_IF_ERROR(ParseString(&header.descr));
      } else if (key == "fortran_order") {
        seen = &has_fortran_order;
        MLCLUST_RETURN_IF_ERROR(ParseBool(&header.fortran_order));
      } else if (key == "shape") {
        seen = &has_shape;
        MLCLUST_RETURN_IF_ERROR(ParseShape(&header.shape));
      } else {
        return Error(absl::StrCat("unexpected key ", Quote(key),
                                  " (a .npy header has 'descr', 'fortran_order' and 'shape')"));
      }
      if (*seen) return Error(absl::StrCat("key ", Quote(key), " appears twice"));
      *seen = true;
      SkipSpace();
      if (Consume(',')) {
        SkipSpace();
      } else if (Peek() != '}') {
        return Error("expected ',' or '}'");
      }
    }
    SkipSpace();
    if (position_ != text_.size()) return Error("unexpected text after the dict");
    for (const auto& [present, name] :
         {std::pair{has_descr, "descr"}, std::pair{has_fortran_order, "fortran_order"},
          std::pair{has_shape, "shape"}}) {
      if (!present) return Error(absl::StrCat("key '", name, "' is missing"));
    }
    return header;
  }

 private:
  // End of text reads as '\0', which no rule accepts.
  char Peek() const { return position_ < text_.size() ? text_[position_] : '\0'; }
  bool Consume(char c) {
    if (Peek() != c || position_ == text_.size()) return false;
    ++position_;
    return true;
  }
  void SkipSpace() {
    // Inside braces Python joins lines, so newlines are whitespace too.
    while (position_ < text_.size() &&
           (text_[position_] == ' ' || text_[position_] == '\t' || text_[position_] == '\n' ||
            text_[position_] == '\r' || text_[position_] == '\f')) {
      ++position_;
    }
  }

  absl::Status Error(absl::string_view what) const {
    return absl::InvalidArgumentError(absl::StrCat("header is not a valid .npy header: ", what,
                                                   " at header byte ", position_, " in ",
                                                   Quote(TrimmedHeader(), 120)));
  }

  // The header without NumPy's padding, for messages.
  absl::string_view TrimmedHeader() const {
    absl::string_view text = text_;
    while (!text.empty() && (text.back() == ' ' || text.back() == '\n')) text.remove_suffix(1);
    return text;
  }

  absl::Status ParseString(std::string* out) {
    const char quote = Peek();
    if (quote != '\'' && quote != '"') return Error("expected a quoted string");
    ++position_;
    const size_t start = position_;
    while (position_ < text_.size() && text_[position_] != quote) {
      const unsigned char c = static_cast<unsigned char>(text_[position_]);
      if (c == '\\') return Error("escape sequences in strings are not supported");
      if (c < 0x20 || c >= 0x7f) return Error("unexpected character in a string");
      if (position_ - start >= 64) return Error("string longer than 64 characters");
      ++position_;
    }
    if (position_ == text_.size()) return Error("unterminated string");
    *out = std::string(text_.substr(start, position_ - start));
    ++position_;  // The closing quote.
    return absl::OkStatus();
  }

  absl::Status ParseBool(bool* out) {
    const size_t start = position_;
    while (position_ < text_.size() && absl::ascii_isalnum(text_[position_])) ++position_;
    const absl::string_view word = text_.substr(start, position_ - start);
    if (word == "True") {
      *out = true;
    } else if (word == "False") {
      *out = false;
    } else {
      position_ = start;
      return Error("'fortran_order' is not True or False");
    }
    return absl::OkStatus();
  }

  // A Python tuple of non-negative decimal integers: (), (m,), (m, d), (m, d,).
  absl::Status ParseShape(std::vector<uint64_t>* shape) {
    if (!Consume('(')) return Error("'shape' is not a tuple");
    SkipSpace();
    bool trailing_comma = false;
    while (!Consume(')')) {
      if (shape->size() == kMaxNpyRank) {
        return Error(absl::StrCat("shape has more than ", kMaxNpyRank, " entries"));
      }
      if (Peek() == '-') return Error("shape has a negative entry");
      if (!absl::ascii_isdigit(Peek())) return Error("expected an integer in 'shape'");
      const size_t start = position_;
      uint64_t value = 0;
      while (absl::ascii_isdigit(Peek())) {
        if (__builtin_mul_overflow(value, uint64_t{10}, &value) ||
            __builtin_add_overflow(value, uint64_t(Peek() - '0'), &value)) {
          return Error("shape entry does not fit in 64 bits");
        }
        ++position_;
      }
      // Python 3 refuses 007; it would not be a NumPy header.
      if (text_[start] == '0' && position_ - start > 1) {
        position_ = start;
        return Error("integer with a leading zero in 'shape'");
      }
      shape->push_back(value);
      SkipSpace();
      trailing_comma = Consume(',');
      if (trailing_comma) {
        SkipSpace();
      } else if (Peek() != ')') {
        return Error("expected ',' or ')' in 'shape'");
      }
    }
    // (3) is the integer 3 in Python; a 1-tuple is written (3,).
    if (shape->size() == 1 && !trailing_comma) {
      return Error("'shape' is an integer in parentheses, not a tuple");
    }
    return absl::OkStatus();
  }

  absl::string_view text_;
  size_t position_ = 0;
};

// Parses the preamble and header of a .npy file; on success `*data_offset` is where the
// data starts.
absl::StatusOr<NpyHeader> ReadNpyHeader(ByteSource& source, uint64_t* data_offset) {
  const uint64_t file_size = source.size();
  unsigned char preamble[12] = {};
  const size_t head = static_cast<size_t>(std::min<uint64_t>(file_size, sizeof(preamble)));
  MLCLUST_RETURN_IF_ERROR(source.ReadAt(0, head, preamble));
  const absl::string_view magic(reinterpret_cast<const char*>(preamble),
                                std::min(head, kNpyMagic.size()));
  if (!absl::StartsWith(kNpyMagic, magic)) {
    return absl::InvalidArgumentError(absl::StrCat("not a .npy file: it starts with ", Quote(magic),
                                                   ", not the magic '\\x93NUMPY'"));
  }
  if (file_size < 8) {
    return absl::InvalidArgumentError(
        absl::StrCat("truncated .npy: ", file_size, " bytes, the magic and version need 8"));
  }
  const int major = preamble[6], minor = preamble[7];
  if (major < 1 || major > 3 || minor != 0) {
    return absl::InvalidArgumentError(absl::StrCat(".npy format version ", major, ".", minor,
                                                   " is not supported (1.0, 2.0 and 3.0 are)"));
  }
  const uint64_t preamble_size = major == 1 ? 10 : 12;
  if (file_size < preamble_size) {
    return absl::InvalidArgumentError(absl::StrCat("truncated .npy: ", file_size,
                                                   " bytes, the version ", major,
                                                   ".0 preamble needs ", preamble_size));
  }
  const uint64_t header_size = major == 1 ? uint64_t{preamble[8]} | uint64_t{preamble[9]} << 8
                                          : uint64_t{LoadLittleEndian32(preamble + 8)};
  // Both terms are small, so the sum cannot overflow.
  const uint64_t header_end = preamble_size + header_size;
  if (header_end > file_size) {
    return absl::InvalidArgumentError(
        absl::StrCat("truncated .npy: the header declares ", header_size, " bytes, ending at byte ",
                     header_end, ", but the file has ", file_size, " bytes"));
  }
  if (header_size > kMaxNpyHeaderBytes) {
    return absl::InvalidArgumentError(absl::StrCat(
        ".npy header of ", header_size, " bytes is over the limit of ", kMaxNpyHeaderBytes));
  }
  std::string text(static_cast<size_t>(header_size), '\0');
  MLCLUST_RETURN_IF_ERROR(source.ReadAt(preamble_size, text.size(), text.data()));
  *data_offset = header_end;
  return NpyHeaderParser(text).Parse();
}

absl::StatusOr<PointSet> ReadNpy(ByteSource& source, const PointReadOptions& options) {
  uint64_t data_offset = 0;
  MLCLUST_ASSIGN_OR_RETURN(const NpyHeader header, ReadNpyHeader(source, &data_offset));

  // '<' little-endian, '>' big-endian; NumPy always writes one of them for these types.
  const std::string& descr = header.descr;
  if (descr.size() != 3 || (descr[0] != '<' && descr[0] != '>') || descr[1] != 'f' ||
      (descr[2] != '4' && descr[2] != '8')) {
    return absl::InvalidArgumentError(
        absl::StrCat("dtype ", Quote(descr), " is not float32 or float64"));
  }
  const size_t item_size = descr[2] == '4' ? 4 : 8;
  const bool swap = (descr[0] == '<') != (std::endian::native == std::endian::little);

  if (header.shape.size() != 2) {
    return absl::InvalidArgumentError(
        absl::StrCat("shape ", ShapeString(header.shape), " is not 2-D (points, dimensions)"));
  }
  const uint64_t m = header.shape[0], d = header.shape[1];
  MLCLUST_RETURN_IF_ERROR(CheckShapeWithinLimits(m, d, options.limits));
  const uint64_t count = m * d;  // Within max_values, so no overflow here.
  uint64_t data_size = 0, expected_size = 0;
  if (__builtin_mul_overflow(count, uint64_t{item_size}, &data_size) ||
      __builtin_add_overflow(data_offset, data_size, &expected_size) ||
      count > std::numeric_limits<size_t>::max() / item_size) {
    return absl::InvalidArgumentError(
        absl::StrCat("shape ", ShapeString(header.shape), " is too large to address"));
  }
  if (source.size() != expected_size) {
    return absl::InvalidArgumentError(
        absl::StrCat(source.size() < expected_size ? "truncated .npy" : ".npy has trailing bytes",
                     ": shape ", ShapeString(header.shape), " of ", descr, " needs ", data_size,
                     " bytes of data after the ", data_offset, "-byte header, so ", expected_size,
                     " bytes in all, but the file has ", source.size()));
  }

  PointSet points;
  points.dims = static_cast<uint32_t>(d);  // d <= max_dims, a uint32.
  points.values.resize(static_cast<size_t>(count));
  if (item_size == 4 && !swap && !header.fortran_order) {
    MLCLUST_RETURN_IF_ERROR(
        source.ReadAt(data_offset, static_cast<size_t>(data_size), points.values.data()));
    return points;
  }

  // Everything else goes through a bounded buffer: swapped, widened float64 narrowed, and
  // Fortran order (column-major) transposed. (row, column) is where the next value of the
  // file goes.
  constexpr size_t kChunkValues = size_t{1} << 16;
  std::vector<unsigned char> buffer(std::min<uint64_t>(count, kChunkValues) * item_size);
  uint64_t row = 0, column = 0;
  for (uint64_t done = 0; done < count;) {
    const size_t chunk = static_cast<size_t>(std::min<uint64_t>(count - done, kChunkValues));
    MLCLUST_RETURN_IF_ERROR(
        source.ReadAt(data_offset + done * item_size, chunk * item_size, buffer.data()));
    for (size_t k = 0; k < chunk; ++k) {
      float value;
      if (item_size == 4) {
        uint32_t bits;
        std::memcpy(&bits, buffer.data() + 4 * k, 4);
        if (swap) bits = __builtin_bswap32(bits);
        value = std::bit_cast<float>(bits);
      } else {
        uint64_t bits;
        std::memcpy(&bits, buffer.data() + 8 * k, 8);
        if (swap) bits = __builtin_bswap64(bits);
        const double wide = std::bit_cast<double>(bits);
        // Converting a finite double beyond float's range is undefined behaviour, and
        // there is no float that means it. NaN and infinity convert and are named by
        // ValidatePoints.
        if (std::isfinite(wide) && std::fabs(wide) > std::numeric_limits<float>::max()) {
          return absl::InvalidArgumentError(absl::StrCat(
              "point ", row, " coordinate ", column, " is ", wide, ", which overflows float32"));
        }
        value = static_cast<float>(wide);
      }
      points.values[row * d + column] = value;
      if (header.fortran_order) {
        if (++row == m) {
          row = 0;
          ++column;
        }
      } else if (++column == d) {
        column = 0;
        ++row;
      }
    }
    done += chunk;
  }
  return points;
}

// ---------------------------------------------------------------------------------------
// Raw float32.

absl::StatusOr<PointSet> ReadRawFloat32(ByteSource& source, const PointReadOptions& options) {
  if (options.dims == 0) {
    return absl::InvalidArgumentError(
        "raw float32 does not record the number of dimensions: give it with --dims");
  }
  const uint64_t d = options.dims;
  MLCLUST_RETURN_IF_ERROR(CheckShapeWithinLimits(0, d, options.limits));
  const uint64_t point_size = 4 * d;
  if (source.size() % point_size != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat(source.size(), " bytes is not a whole number of ", d,
                     "-dimensional float32 points (", point_size, " bytes each)"));
  }
  const uint64_t m = source.size() / point_size;
  MLCLUST_RETURN_IF_ERROR(CheckShapeWithinLimits(m, d, options.limits));
  if (source.size() >= kNpyMagic.size()) {
    char magic[6];
    MLCLUST_RETURN_IF_ERROR(source.ReadAt(0, sizeof(magic), magic));
    if (absl::string_view(magic, sizeof(magic)) == kNpyMagic) {
      return absl::InvalidArgumentError(
          "starts with the .npy magic: name it .npy to read its header");
    }
  }
  PointSet points;
  points.dims = options.dims;
  points.values.resize(static_cast<size_t>(m * d));
  MLCLUST_RETURN_IF_ERROR(
      source.ReadAt(0, static_cast<size_t>(source.size()), points.values.data()));
  if constexpr (std::endian::native == std::endian::big) {
    for (float& value : points.values) {
      value = std::bit_cast<float>(__builtin_bswap32(std::bit_cast<uint32_t>(value)));
    }
  }
  return points;
}

// ---------------------------------------------------------------------------------------
// CSV and whitespace-separated text.

bool IsBlank(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f' || c == '\r'; }

absl::string_view TrimBlanks(absl::string_view text) {
  while (!text.empty() && IsBlank(text.front())) text.remove_prefix(1);
  while (!text.empty() && IsBlank(text.back())) text.remove_suffix(1);
  return text;
}

// Where `c` next occurs in text[from, size), or text.size(). std::memchr rather than
// absl::string_view::find, which this Abseil build does not inline (a third of the time
// of a large CSV went to the calls).
size_t Find(absl::string_view text, char c, size_t from) {
  if (from >= text.size()) return text.size();  // Also keeps a null data() from memchr.
  const void* found = std::memchr(text.data() + from, c, text.size() - from);
  return found == nullptr ? text.size()
                          : static_cast<size_t>(static_cast<const char*>(found) - text.data());
}

// Splits `line` (not blank) into fields: at every comma, each field trimmed, or at runs of
// blanks.
void SplitFields(absl::string_view line, bool comma_separated,
                 std::vector<absl::string_view>* fields) {
  fields->clear();
  if (comma_separated) {
    for (size_t start = 0;;) {
      const size_t comma = Find(line, ',', start);
      fields->push_back(TrimBlanks(line.substr(start, comma - start)));
      if (comma == line.size()) return;
      start = comma + 1;
    }
  }
  size_t position = 0;
  while (true) {
    while (position < line.size() && IsBlank(line[position])) ++position;
    if (position == line.size()) return;
    const size_t start = position;
    while (position < line.size() && !IsBlank(line[position])) ++position;
    fields->push_back(line.substr(start, position - start));
  }
}

enum class FieldKind { kNumber, kNotANumber, kOverflow };

FieldKind ParseField(absl::string_view field, float* value) {
  // from_chars takes no '+'; "+-1" must stay refused.
  if (field.size() > 1 && field[0] == '+' && field[1] != '-') field.remove_prefix(1);
  const char* const end = field.data() + field.size();
  const auto [stop, error] = std::from_chars(field.data(), end, *value);
  if (stop != end || error == std::errc::invalid_argument || field.empty()) {
    return FieldKind::kNotANumber;
  }
  if (error == std::errc::result_out_of_range) {
    // Too large or too small for float32; std::from_chars leaves the value unset, Abseil's
    // gives +-max on overflow and the rounded value (+-0) on underflow, which is kept.
    absl::from_chars(field.data(), end, *value);
    if (std::fabs(*value) > 1) return FieldKind::kOverflow;
  }
  return FieldKind::kNumber;
}

absl::StatusOr<PointSet> ParseText(absl::string_view text, const PointReadOptions& options) {
  if (absl::StartsWith(text, "\xEF\xBB\xBF")) text.remove_prefix(3);  // UTF-8 byte-order mark.
  PointSet points;
  std::vector<absl::string_view> fields;
  bool comma_separated = false;
  bool seen_first_line = false;
  uint64_t first_data_row = 0;
  uint64_t row = 0;  // 1-based line number in the file.
  for (size_t position = 0; position < text.size();) {
    const size_t end = Find(text, '\n', position);
    const absl::string_view line = text.substr(position, end - position);
    position = end + 1;
    ++row;
    if (TrimBlanks(line).empty()) continue;

    if (!seen_first_line) comma_separated = Find(line, ',', 0) != line.size();
    SplitFields(line, comma_separated, &fields);
    if (!seen_first_line) {
      seen_first_line = true;
      // A header has no field that reads as a number; "x,1.5,z" is a typo, not a header.
      const bool is_header = std::none_of(fields.begin(), fields.end(), [](auto field) {
        float ignored;
        return ParseField(field, &ignored) != FieldKind::kNotANumber;
      });
      if (is_header) continue;
    }

    if (first_data_row == 0) {
      first_data_row = row;
      if (fields.size() > options.limits.max_dims) {
        return absl::InvalidArgumentError(absl::StrCat("row ", row, " has ", fields.size(),
                                                       " fields, over the limit of ",
                                                       options.limits.max_dims, " dimensions"));
      }
      points.dims = static_cast<uint32_t>(fields.size());
      // Guess the rest from this line's length (+12%), so that a file of similar lines
      // fills the vector without regrowing; every value takes at least two bytes, which
      // bounds the guess for a file whose first line is unusually short.
      const uint64_t rest = text.size() - (position - line.size() - 1);
      const uint64_t guess = rest / (line.size() + 1) * points.dims * 9 / 8 + points.dims;
      points.values.reserve(
          static_cast<size_t>(std::min({guess, rest / 2 + 1, options.limits.max_values})));
    } else if (fields.size() != points.dims) {
      return absl::InvalidArgumentError(absl::StrCat("row ", row, " has ", fields.size(),
                                                     " fields but row ", first_data_row,
                                                     " (the first data row) has ", points.dims));
    }
    if (points.values.size() + points.dims > options.limits.max_values) {
      return absl::InvalidArgumentError(absl::StrCat(
          "row ", row, ": more than ", options.limits.max_values, " values, the limit"));
    }
    for (size_t column = 0; column < fields.size(); ++column) {
      float value = 0;
      const FieldKind kind = ParseField(fields[column], &value);
      if (kind != FieldKind::kNumber || !std::isfinite(value)) {
        const std::string where = absl::StrCat("row ", row, " column ", column + 1);
        if (fields[column].empty()) return absl::InvalidArgumentError(where + " is empty");
        return absl::InvalidArgumentError(
            absl::StrCat(where, ": ", Quote(fields[column]),
                         kind == FieldKind::kNotANumber ? " is not a number"
                         : kind == FieldKind::kOverflow ? " overflows float32"
                                                        : " is not finite"));
      }
      points.values.push_back(value);
    }
  }
  if (first_data_row == 0) return absl::InvalidArgumentError("no data rows (m = 0 points)");
  return points;
}

// ---------------------------------------------------------------------------------------

enum class Format { kNpy, kText, kRawFloat32, kUnknown };

Format FormatOf(const std::string& path) {
  const std::string extension =
      absl::AsciiStrToLower(std::filesystem::path(path).extension().string());
  if (extension == ".npy") return Format::kNpy;
  if (extension == ".csv" || extension == ".txt") return Format::kText;
  if (extension == ".f32" || extension == ".bin" || extension == ".raw") {
    return Format::kRawFloat32;
  }
  return Format::kUnknown;
}

absl::StatusOr<PointSet> ReadPointsFileUnnamed(const std::string& path,
                                               const PointReadOptions& options) {
  const Format format = FormatOf(path);
  // A missing file is NOT_FOUND even with an extension we do not read.
  MLCLUST_ASSIGN_OR_RETURN(const std::unique_ptr<FileSource> source, FileSource::Open(path));
  absl::StatusOr<PointSet> points;
  switch (format) {
    case Format::kNpy:
      points = ReadNpy(*source, options);
      break;
    case Format::kRawFloat32:
      points = ReadRawFloat32(*source, options);
      break;
    case Format::kText: {
      std::string text(static_cast<size_t>(source->size()), '\0');
      MLCLUST_RETURN_IF_ERROR(source->ReadAt(0, text.size(), text.data()));
      points = ParseText(text, options);
      break;
    }
    case Format::kUnknown:
      return absl::InvalidArgumentError(absl::StrCat(
          "unknown point file extension ", Quote(std::filesystem::path(path).extension().string()),
          " (expected .npy, .csv, .txt, or raw float32 .f32, .bin, .raw)"));
  }
  if (!points.ok()) return points.status();
  return Finish(*std::move(points), options);
}

absl::Status WithPrefix(absl::string_view prefix, const absl::Status& status) {
  return absl::Status(status.code(), absl::StrCat(prefix, ": ", status.message()));
}

}  // namespace

absl::StatusOr<PointSet> ReadPointsFile(const std::string& path, const PointReadOptions& options) {
  absl::StatusOr<PointSet> points = ReadPointsFileUnnamed(path, options);
  if (!points.ok()) return WithPrefix(path, points.status());
  return points;
}

absl::StatusOr<PointSet> DecodePointsNpy(absl::string_view bytes, const PointReadOptions& options) {
  MemorySource source(bytes);
  MLCLUST_ASSIGN_OR_RETURN(PointSet points, ReadNpy(source, options));
  return Finish(std::move(points), options);
}

absl::StatusOr<PointSet> DecodePointsText(absl::string_view text, const PointReadOptions& options) {
  MLCLUST_ASSIGN_OR_RETURN(PointSet points, ParseText(text, options));
  return Finish(std::move(points), options);
}

absl::Status WritePointsNpy(const std::string& path, const PointSet& points) {
  if (points.dims == 0 || points.values.size() % points.dims != 0) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": cannot write ", points.values.size(),
                                                   " values as ", points.dims,
                                                   "-dimensional points"));
  }
  std::string header = absl::StrCat("{'descr': '<f4', 'fortran_order': False, 'shape': (",
                                    points.num_points(), ", ", points.dims, "), }");
  // NumPy pads so that the data starts on a 64-byte boundary: preamble (10) + header + '\n'.
  header.append((64 - (10 + header.size() + 1) % 64) % 64, ' ');
  header.push_back('\n');
  std::string preamble(kNpyMagic);
  preamble.push_back('\x01');
  preamble.push_back('\x00');
  preamble.push_back(static_cast<char>(header.size() & 0xff));
  preamble.push_back(static_cast<char>(header.size() >> 8));  // Under 200 bytes: fits 1.0.

  std::vector<float> swapped;
  const float* data = points.values.data();
  if constexpr (std::endian::native == std::endian::big) {
    swapped = points.values;
    for (float& value : swapped) {
      value = std::bit_cast<float>(__builtin_bswap32(std::bit_cast<uint32_t>(value)));
    }
    data = swapped.data();
  }
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) return WithPrefix(path, ErrnoError(errno, "cannot open for writing"));
  bool written =
      std::fwrite(preamble.data(), 1, preamble.size(), file) == preamble.size() &&
      std::fwrite(header.data(), 1, header.size(), file) == header.size() &&
      std::fwrite(data, sizeof(float), points.values.size(), file) == points.values.size();
  const int write_error = errno;
  if (std::fclose(file) != 0 && written) return WithPrefix(path, ErrnoError(errno, "write failed"));
  if (!written) return WithPrefix(path, ErrnoError(write_error, "write failed"));
  return absl::OkStatus();
}

}  // namespace mlclust
