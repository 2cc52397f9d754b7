#include "core/io/points_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <initializer_list>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/points/points.h"
#include "tests/fixtures/files.h"

namespace mlclust {
namespace {

using ::testing::ElementsAre;
using ::testing::ElementsAreArray;
using ::testing::HasSubstr;
using ::testing::StartsWith;

// ---------------------------------------------------------------------------------------
// Building files byte by byte, independent of the writer under test.

void AppendLittleEndian(std::string& out, uint64_t value, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(static_cast<char>(value >> (8 * i) & 0xff));
}

std::string Float32Bytes(std::initializer_list<float> values) {
  std::string out;
  for (float value : values) AppendLittleEndian(out, std::bit_cast<uint32_t>(value), 4);
  return out;
}

std::string Float64Bytes(std::initializer_list<double> values) {
  std::string out;
  for (double value : values) AppendLittleEndian(out, std::bit_cast<uint64_t>(value), 8);
  return out;
}

// A .npy file of format `major`.0 whose header is `dict`, padded as NumPy pads it (spaces
// and a newline, so that the data starts at a multiple of 64 bytes).
std::string NpyFile(std::string dict, const std::string& data, int major = 1) {
  const size_t preamble_size = major == 1 ? 10 : 12;
  dict.append((64 - (preamble_size + dict.size() + 1) % 64) % 64, ' ');
  dict.push_back('\n');
  std::string out("\x93NUMPY", 6);
  out.push_back(static_cast<char>(major));
  out.push_back('\0');
  AppendLittleEndian(out, dict.size(), major == 1 ? 2 : 4);
  return out + dict + data;
}

constexpr char kDict23[] = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }";

absl::StatusOr<PointSet> Decode(const std::string& bytes, PointReadOptions options = {}) {
  return DecodePointsNpy(bytes, options);
}

void ExpectInvalid(const absl::StatusOr<PointSet>& result, const std::string& message) {
  ASSERT_FALSE(result.ok()) << "expected an error containing: " << message;
  EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument) << result.status();
  EXPECT_THAT(std::string(result.status().message()), HasSubstr(message));
}

using PointsIoTest = testing::TempDirectoryTest;
using testing::ReadFileBytes;

// ---------------------------------------------------------------------------------------
// .npy: what is read.

TEST_F(PointsIoTest, WriterRoundTripsFloat32Exactly) {
  PointSet points;
  points.dims = 3;
  points.values = {1.5f, -2.25f, 0.1f, 3.4028235e38f, -1.4e-45f, 0.0f, -0.0f, 7.0f, 1e-20f};
  const std::string path = Path("round_trip.npy");
  ASSERT_TRUE(WritePointsNpy(path, points).ok());

  // The bytes are what NumPy 1.x writes for np.save of a (3, 3) float32 array.
  const std::string bytes = ReadFileBytes(path);
  const std::string dict = "{'descr': '<f4', 'fortran_order': False, 'shape': (3, 3), }";
  ASSERT_EQ(bytes.size(), 128u + 36u);
  EXPECT_EQ(bytes.substr(0, 10), std::string("\x93NUMPY\x01\x00\x76\x00", 10));
  EXPECT_EQ(bytes.substr(10, dict.size()), dict);
  EXPECT_EQ(bytes[127], '\n');
  EXPECT_EQ(bytes.substr(128), Float32Bytes({1.5f, -2.25f, 0.1f, 3.4028235e38f, -1.4e-45f, 0.0f,
                                             -0.0f, 7.0f, 1e-20f}));

  absl::StatusOr<PointSet> read = ReadPointsFile(path, {});
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->dims, 3u);
  ASSERT_EQ(read->values.size(), 9u);
  for (size_t i = 0; i < 9; ++i) {
    EXPECT_EQ(std::bit_cast<uint32_t>(read->values[i]), std::bit_cast<uint32_t>(points.values[i]))
        << i;
  }
}

TEST_F(PointsIoTest, WriterRefusesDimsZeroAndPartialPoints) {
  PointSet points;
  points.values = {1, 2};
  EXPECT_EQ(WritePointsNpy(Path("a.npy"), points).code(), absl::StatusCode::kInvalidArgument);
  points.dims = 3;
  EXPECT_EQ(WritePointsNpy(Path("a.npy"), points).code(), absl::StatusCode::kInvalidArgument);
  points.dims = 1;
  EXPECT_EQ(WritePointsNpy(Path("no/such/dir/a.npy"), points).code(), absl::StatusCode::kNotFound);
}

TEST_F(PointsIoTest, HandCraftedVersions1To3ReadAlike) {
  const std::string data = Float32Bytes({1, 2, 3, 4, 5, 6});
  for (int major : {1, 2, 3}) {
    const std::string bytes = NpyFile(kDict23, data, major);
    EXPECT_EQ(bytes.size() % 64, 24u) << "data starts at a multiple of 64";
    absl::StatusOr<PointSet> points =
        ReadPointsFile(Write(absl::StrCat("v", major, ".npy"), bytes), {});
    ASSERT_TRUE(points.ok()) << major << ": " << points.status();
    EXPECT_EQ(points->dims, 3u);
    EXPECT_THAT(points->values, ElementsAre(1, 2, 3, 4, 5, 6)) << major;
  }
}

TEST_F(PointsIoTest, HeaderSpellingsPythonAccepts) {
  const std::string data = Float32Bytes({1, 2, 3, 4, 5, 6});
  for (const std::string dict : {
           "{'shape': (2, 3), 'fortran_order': False, 'descr': '<f4'}",
           "{\"descr\": \"<f4\", \"fortran_order\": False, \"shape\": (2,3,)}",
           "  {'descr':'<f4','fortran_order':False,'shape':( 2 , 3 )}",
           "{'descr': '<f4',\n 'fortran_order': False,\t'shape': (2, 3), }",
       }) {
    absl::StatusOr<PointSet> points = Decode(NpyFile(dict, data));
    ASSERT_TRUE(points.ok()) << dict << ": " << points.status();
    EXPECT_THAT(points->values, ElementsAre(1, 2, 3, 4, 5, 6)) << dict;
  }
  // No newline or padding at all: the header ends where the dict does.
  std::string bare("\x93NUMPY\x01\x00", 8);
  const std::string dict(kDict23);
  AppendLittleEndian(bare, dict.size(), 2);
  absl::StatusOr<PointSet> points = Decode(bare + dict + data);
  ASSERT_TRUE(points.ok()) << points.status();
  EXPECT_THAT(points->values, ElementsAre(1, 2, 3, 4, 5, 6));
}

TEST_F(PointsIoTest, Float64IsRoundedToFloat32) {
  const std::string bytes =
      NpyFile("{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2), }",
              Float64Bytes({0.1, -1e-50, 3.4028234663852886e38, 123456789.0}));
  absl::StatusOr<PointSet> points = ReadPointsFile(Write("f8.npy", bytes), {});
  ASSERT_TRUE(points.ok()) << points.status();
  EXPECT_EQ(points->dims, 2u);
  EXPECT_THAT(points->values,
              ElementsAre(0.1f, -0.0f, std::numeric_limits<float>::max(), 123456792.0f));
  EXPECT_TRUE(std::signbit(points->values[1]));
}

TEST_F(PointsIoTest, Float64BeyondFloat32IsRefused) {
  const std::string dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2), }";
  ExpectInvalid(Decode(NpyFile(dict, Float64Bytes({1, 2, -1e300, 4}))),
                "point 1 coordinate 0 is -1e+300, which overflows float32");
  // Just past float32's largest value: no float32 means it.
  ExpectInvalid(Decode(NpyFile(dict, Float64Bytes({1, 3.40282357e38, 3, 4}))),
                "point 0 coordinate 1");
  // NaN and infinity convert, and validation names them.
  ExpectInvalid(Decode(NpyFile(dict, Float64Bytes({1, 2, 3, -INFINITY}))),
                "point 1 coordinate 1 is -inf");
}

TEST_F(PointsIoTest, FortranOrderIsTransposed) {
  // The (2, 3) array [[1, 2, 3], [4, 5, 6]] stored column by column.
  absl::StatusOr<PointSet> points =
      Decode(NpyFile("{'descr': '<f4', 'fortran_order': True, 'shape': (2, 3), }",
                     Float32Bytes({1, 4, 2, 5, 3, 6}), 2));
  ASSERT_TRUE(points.ok()) << points.status();
  EXPECT_EQ(points->dims, 3u);
  EXPECT_THAT(points->values, ElementsAre(1, 2, 3, 4, 5, 6));

  points = Decode(NpyFile("{'descr': '<f8', 'fortran_order': True, 'shape': (3, 2), }",
                          Float64Bytes({1, 3, 5, 2, 4, 6})));
  ASSERT_TRUE(points.ok()) << points.status();
  EXPECT_EQ(points->dims, 2u);
  EXPECT_THAT(points->values, ElementsAre(1, 2, 3, 4, 5, 6));
}

TEST_F(PointsIoTest, BigEndianIsSwapped) {
  std::string data;
  for (float value : {1.0f, -2.0f}) {
    const uint32_t bits = std::bit_cast<uint32_t>(value);
    for (int i = 3; i >= 0; --i) data.push_back(static_cast<char>(bits >> (8 * i) & 0xff));
  }
  absl::StatusOr<PointSet> points =
      Decode(NpyFile("{'descr': '>f4', 'fortran_order': False, 'shape': (1, 2), }", data));
  ASSERT_TRUE(points.ok()) << points.status();
  EXPECT_THAT(points->values, ElementsAre(1.0f, -2.0f));
}

TEST_F(PointsIoTest, ChunkedConversionCoversMoreThanOneBuffer) {
  // 70000 x 2 float64 values in Fortran order cross the reader's 65536-value buffer.
  const uint64_t m = 70000;
  std::string data;
  for (uint64_t column = 0; column < 2; ++column) {
    for (uint64_t row = 0; row < m; ++row) {
      AppendLittleEndian(data, std::bit_cast<uint64_t>(double(row * 2 + column)), 8);
    }
  }
  absl::StatusOr<PointSet> points =
      Decode(NpyFile("{'descr': '<f8', 'fortran_order': True, 'shape': (70000, 2), }", data));
  ASSERT_TRUE(points.ok()) << points.status();
  ASSERT_EQ(points->values.size(), 2 * m);
  for (uint64_t i = 0; i < 2 * m; ++i) ASSERT_EQ(points->values[i], float(i)) << i;
}

// ---------------------------------------------------------------------------------------
// .npy: what is refused.

TEST_F(PointsIoTest, RefusesOtherDtypes) {
  const std::string path =
      Write("x.npy", NpyFile("{'descr': '<i8', 'fortran_order': False, 'shape': (2, 3), }",
                             std::string(48, '\0')));
  absl::StatusOr<PointSet> points = ReadPointsFile(path, {});
  ExpectInvalid(points, "dtype '<i8' is not float32 or float64");
  EXPECT_THAT(std::string(points.status().message()), StartsWith(path + ": "));

  ExpectInvalid(Decode(NpyFile("{'descr': '<f2', 'fortran_order': False, 'shape': (2, 3), }",
                               std::string(12, '\0'))),
                "dtype '<f2' is not float32 or float64");
  ExpectInvalid(Decode(NpyFile("{'descr': 'f4', 'fortran_order': False, 'shape': (2, 3), }",
                               std::string(24, '\0'))),
                "dtype 'f4' is not");
  ExpectInvalid(Decode(NpyFile("{'descr': [('x', '<f4'), ('y', '<f4')], 'fortran_order': False, "
                               "'shape': (2,), }",
                               std::string(16, '\0'))),
                "dtype is structured");
}

TEST_F(PointsIoTest, RefusesShapesThatAreNot2D) {
  const std::string data = Float32Bytes({1, 2, 3, 4, 5, 6, 7, 8, 9, 10});
  ExpectInvalid(ReadPointsFile(Write("x.npy", NpyFile("{'descr': '<f4', 'fortran_order': False, "
                                                      "'shape': (10,), }",
                                                      data)),
                               {}),
                "x.npy: shape (10,) is not 2-D");
  ExpectInvalid(
      Decode(NpyFile("{'descr': '<f4', 'fortran_order': False, 'shape': (1, 2, 5), }", data)),
      "shape (1, 2, 5) is not 2-D");
  ExpectInvalid(
      Decode(NpyFile("{'descr': '<f4', 'fortran_order': False, 'shape': (), }", Float32Bytes({1}))),
      "shape () is not 2-D");
}

TEST_F(PointsIoTest, RefusesTruncatedAndOverlongData) {
  const std::string whole = NpyFile(kDict23, Float32Bytes({1, 2, 3, 4, 5, 6}));
  ASSERT_EQ(whole.size(), 152u);
  ExpectInvalid(Decode(whole.substr(0, 151)),
                "truncated .npy: shape (2, 3) of <f4 needs 24 bytes of data after the 128-byte "
                "header, so 152 bytes in all, but the file has 151");
  ExpectInvalid(ReadPointsFile(Write("t.npy", whole.substr(0, 128)), {}), "the file has 128");
  ExpectInvalid(Decode(whole + "x"), ".npy has trailing bytes");
}

TEST_F(PointsIoTest, RefusesTruncatedHeader) {
  const std::string whole = NpyFile(kDict23, Float32Bytes({1, 2, 3, 4, 5, 6}));
  ExpectInvalid(Decode(whole.substr(0, 40)),
                "the header declares 118 bytes, ending at byte 128, but the file has 40 bytes");
  ExpectInvalid(Decode(whole.substr(0, 9)),
                "truncated .npy: 9 bytes, the version 1.0 preamble "
                "needs 10");
  ExpectInvalid(Decode(whole.substr(0, 5)), "truncated .npy: 5 bytes");
  ExpectInvalid(Decode(""), "truncated .npy: 0 bytes");
  const std::string v2 = NpyFile(kDict23, "", 2);
  ExpectInvalid(Decode(v2.substr(0, 11)), "the version 2.0 preamble needs 12");
}

TEST_F(PointsIoTest, RefusesHeaderLengthBeyondFile) {
  std::string bytes = NpyFile(kDict23, Float32Bytes({1, 2, 3, 4, 5, 6}), 2);
  bytes[8] = bytes[9] = bytes[10] = bytes[11] = '\xff';
  ExpectInvalid(Decode(bytes),
                "the header declares 4294967295 bytes, ending at byte "
                "4294967307, but the file has 152 bytes");
  // Within the file but absurdly long: bounded before it is read.
  std::string padded = NpyFile(std::string(kDict23) + std::string(70000, ' '), "", 2);
  ExpectInvalid(Decode(padded), "over the limit of 65536");
}

TEST_F(PointsIoTest, RefusesGarbageMagicAndVersions) {
  ExpectInvalid(Decode("PK\x03\x04 this is a zip file"), "not a .npy file");
  ExpectInvalid(Decode(std::string("\x93NUMPZ\x01\x00", 8)), "not a .npy file");
  ExpectInvalid(Decode("x"), "not a .npy file");
  std::string bytes = NpyFile(kDict23, Float32Bytes({1, 2, 3, 4, 5, 6}));
  bytes[6] = 4;
  ExpectInvalid(Decode(bytes), ".npy format version 4.0 is not supported");
  bytes[6] = 1;
  bytes[7] = 1;
  ExpectInvalid(Decode(bytes), ".npy format version 1.1 is not supported");
}

TEST_F(PointsIoTest, RefusesMalformedHeaderDicts) {
  struct Case {
    std::string dict;
    std::string message;
  };
  const std::string data = Float32Bytes({1, 2, 3, 4, 5, 6});
  for (const Case& c : std::vector<Case>{
           {"{'descr': '<f4', 'fortran_order': False}", "key 'shape' is missing"},
           {"{'descr': '<f4', 'shape': (2, 3)}", "key 'fortran_order' is missing"},
           {"{'descr': '<f4', 'descr': '<f4', 'fortran_order': False, 'shape': (2, 3)}",
            "key 'descr' appears twice"},
           {"{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), 'x': 1}",
            "unexpected key 'x'"},
           {"{'descr': '<f4', 'fortran_order': 0, 'shape': (2, 3)}", "not True or False"},
           {"{'descr': '<f4', 'fortran_order': Falsey, 'shape': (2, 3)}", "not True or False"},
           {"{'descr': '<f4', 'fortran_order': False, 'shape': (6)}", "not a tuple"},
           {"{'descr': '<f4', 'fortran_order': False, 'shape': [2, 3]}", "not a tuple"},
           {"{'descr': '<f4', 'fortran_order': False, 'shape': (-2, 3)}", "negative"},
           {"{'descr': '<f4', 'fortran_order': False, 'shape': (02, 3)}", "leading zero"},
           {"{'descr': '<f4', 'fortran_order': False, 'shape': (2 3)}", "expected ',' or ')'"},
           {"{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3.0)}", "expected ',' or ')'"},
           {"{'descr': '<f4', 'fortran_order': False, 'shape': (99999999999999999999, 3)}",
            "does not fit in 64 bits"},
           {"{'descr': '<f\\x34', 'fortran_order': False, 'shape': (2, 3)}", "escape"},
           {"{'descr': '<f4, 'fortran_order': False, 'shape': (2, 3)}", "expected ',' or '}'"},
           {"{'descr' '<f4', 'fortran_order': False, 'shape': (2, 3)}", "expected ':'"},
           {"{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3)} x", "after the dict"},
           {"{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3)", "expected ',' or '}'"},
           {"{'descr': '<f4' 'fortran_order': False, 'shape': (2, 3)}", "expected ',' or '}'"},
           {"{'descr': '<f4',, 'fortran_order': False, 'shape': (2, 3)}", "quoted string"},
           {"{descr: '<f4', 'fortran_order': False, 'shape': (2, 3)}", "quoted string"},
           {"'descr': '<f4', 'fortran_order': False, 'shape': (2, 3)", "expected '{'"},
           {std::string("{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3)}\0", 58),
            "after the dict"},
           {"{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), 'descr\xe9': 1}",
            "unexpected character"},
           {"", "expected '{'"},
       }) {
    SCOPED_TRACE(c.dict);
    ExpectInvalid(Decode(NpyFile(c.dict, data)), c.message);
  }
  // The message shows where the parser stopped and the header without its padding.
  ExpectInvalid(Decode(NpyFile("{'descr': '<f4', 'fortran_order': 0, 'shape': (2, 3)}", data)),
                "header is not a valid .npy header: 'fortran_order' is not True or False at "
                "header byte 34 in '{'descr': '<f4', 'fortran_order': 0, 'shape': (2, 3)}'");
}

TEST_F(PointsIoTest, HugeDeclaredShapeIsRefusedWithoutAllocating) {
  const std::string tiny = Float32Bytes({1, 2, 3});
  // Over the limits: refused on the header alone.
  ExpectInvalid(Decode(NpyFile("{'descr': '<f4', 'fortran_order': False, "
                               "'shape': (1099511627776, 3), }",
                               tiny)),
                "m x d = 1099511627776 x 3 values is over the limit of 2147483648");
  ExpectInvalid(Decode(NpyFile("{'descr': '<f4', 'fortran_order': False, "
                               "'shape': (9223372036854775808, 9223372036854775808), }",
                               tiny)),
                "d = 9223372036854775808 dimensions is over the limit of 1024");
  ExpectInvalid(Decode(NpyFile("{'descr': '<f4', 'fortran_order': False, "
                               "'shape': (9223372036854775808, 2), }",
                               tiny)),
                "over the limit");
  // Within limits that allow anything, the file's length refuses it: the 6 PiB of floats
  // were never allocated (that would throw std::bad_alloc and end the test).
  PointReadOptions unlimited;
  unlimited.limits.max_dims = std::numeric_limits<uint32_t>::max();
  unlimited.limits.max_values = std::numeric_limits<uint64_t>::max();
  ExpectInvalid(Decode(NpyFile("{'descr': '<f8', 'fortran_order': True, "
                               "'shape': (1099511627776, 1536), }",
                               tiny),
                       unlimited),
                "truncated .npy");
  ExpectInvalid(Decode(NpyFile("{'descr': '<f8', 'fortran_order': False, "
                               "'shape': (4611686018427387904, 1), }",
                               tiny),
                       unlimited),
                "too large to address");
  // A raw file is sized by its length, which the limits bound.
  PointReadOptions small;
  small.dims = 3;
  small.limits.max_values = 5;
  ExpectInvalid(ReadPointsFile(Write("big.f32", Float32Bytes({1, 2, 3, 4, 5, 6})), small),
                "m x d = 2 x 3 values is over the limit of 5");
}

TEST_F(PointsIoTest, NpyResultsAreValidated) {
  ExpectInvalid(Decode(NpyFile(kDict23, Float32Bytes({1, 2, 3, 4, 5, NAN}))),
                "point 1 coordinate 2 is nan");
  ExpectInvalid(Decode(NpyFile("{'descr': '<f4', 'fortran_order': False, 'shape': (0, 3), }", "")),
                "m = 0 points");
  ExpectInvalid(Decode(NpyFile("{'descr': '<f4', 'fortran_order': False, 'shape': (3, 0), }", "")),
                "d = 0 dimensions");
  PointReadOptions options;
  options.limits.max_dims = 2;
  ExpectInvalid(Decode(NpyFile(kDict23, Float32Bytes({1, 2, 3, 4, 5, 6})), options),
                "d = 3 dimensions is over the limit of 2");
  options = {};
  options.dims = 4;
  ExpectInvalid(Decode(NpyFile(kDict23, Float32Bytes({1, 2, 3, 4, 5, 6})), options),
                "d = 3 dimensions but --dims 4 was given");
  options.dims = 3;
  EXPECT_TRUE(Decode(NpyFile(kDict23, Float32Bytes({1, 2, 3, 4, 5, 6})), options).ok());
}

// Random damage to a valid file must give an error or a valid point set, never a crash or
// a read out of bounds (run under valgrind/ASan to see the latter).
TEST_F(PointsIoTest, RandomMutationsOfANpyNeverCrash) {
  std::vector<std::string> seeds = {
      NpyFile(kDict23, Float32Bytes({1, 2, 3, 4, 5, 6})),
      NpyFile("{'descr': '<f8', 'fortran_order': True, 'shape': (3, 2), }",
              Float64Bytes({1, 3, 5, 2, 4, 6}), 2),
      NpyFile("{'descr': '>f4', 'fortran_order': False, 'shape': (1, 4), }",
              Float32Bytes({1, 2, 3, 4}), 3),
  };
  std::mt19937 random(12345);
  auto below = [&random](size_t n) {
    return static_cast<size_t>(std::uniform_int_distribution<uint64_t>(0, n - 1)(random));
  };
  const std::string tokens[] = {"'",
                                "(",
                                ")",
                                ",",
                                "{",
                                "}",
                                ":",
                                "9",
                                "0",
                                "-",
                                " ",
                                "\n",
                                "True",
                                "'<f8'",
                                "'shape'",
                                "'descr'",
                                "99999999999999999999",
                                "\xff\xff\xff\xff",
                                "\\",
                                "1,"};
  int accepted = 0;
  for (int iteration = 0; iteration < 20000; ++iteration) {
    std::string bytes = seeds[below(seeds.size())];
    const size_t mutations = 1 + below(4);
    for (size_t k = 0; k < mutations && !bytes.empty(); ++k) {
      const size_t at = below(bytes.size());
      switch (below(6)) {
        case 0:  // Flip a bit.
          bytes[at] = static_cast<char>(bytes[at] ^ (1 << below(8)));
          break;
        case 1:  // Set a byte.
          bytes[at] = static_cast<char>(below(256));
          break;
        case 2:  // Truncate.
          bytes.resize(at);
          break;
        case 3:  // Delete a run.
          bytes.erase(at, 1 + below(8));
          break;
        case 4:  // Insert a token.
          bytes.insert(at, tokens[below(std::size(tokens))]);
          break;
        case 5:  // Damage the version or the header length.
          bytes[std::min(bytes.size() - 1, 6 + below(6))] = static_cast<char>(below(256));
          break;
      }
    }
    absl::StatusOr<PointSet> points = DecodePointsNpy(bytes);
    if (points.ok()) {
      ++accepted;
      ASSERT_TRUE(ValidatePoints(*points).ok()) << iteration;
      ASSERT_EQ(points->values.size() % points->dims, 0u) << iteration;
    } else {
      ASSERT_EQ(points.status().code(), absl::StatusCode::kInvalidArgument)
          << iteration << ": " << points.status();
      ASSERT_FALSE(points.status().message().empty());
    }
  }
  // Some mutations only touch the data or the padding and must still read.
  EXPECT_GT(accepted, 100);
}

// ---------------------------------------------------------------------------------------
// CSV and text.

TEST_F(PointsIoTest, CsvWithHeader) {
  absl::StatusOr<PointSet> points =
      ReadPointsFile(Write("p.csv", "x,y,z\n1,2,3\n-4.5, 5e2 ,+6\n"), {});
  ASSERT_TRUE(points.ok()) << points.status();
  EXPECT_EQ(points->dims, 3u);
  EXPECT_THAT(points->values, ElementsAre(1, 2, 3, -4.5f, 500, 6));
}

TEST_F(PointsIoTest, CsvWithoutHeaderWithCrlfBomAndEmptyLines) {
  absl::StatusOr<PointSet> points =
      DecodePointsText("\xEF\xBB\xBF\r\n0.1,0.2\r\n\r\n   \r\n.5,5.\r\n1e-50,-0\r\n\n");
  ASSERT_TRUE(points.ok()) << points.status();
  EXPECT_EQ(points->dims, 2u);
  EXPECT_THAT(points->values, ElementsAre(0.1f, 0.2f, 0.5f, 5.0f, 0.0f, -0.0f));
}

TEST_F(PointsIoTest, WhitespaceSeparatedText) {
  // NumPy's savetxt(header=...) writes "# x y z".
  absl::StatusOr<PointSet> points = ReadPointsFile(
      Write("p.txt", "# x y z\n  1\t2   3 \n\n4 5\t\t6\n7 8 9"), {});  // No final newline.
  ASSERT_TRUE(points.ok()) << points.status();
  EXPECT_EQ(points->dims, 3u);
  EXPECT_THAT(points->values, ElementsAre(1, 2, 3, 4, 5, 6, 7, 8, 9));

  points = DecodePointsText("1\n2\n3\n");
  ASSERT_TRUE(points.ok()) << points.status();
  EXPECT_EQ(points->dims, 1u);
  EXPECT_THAT(points->values, ElementsAre(1, 2, 3));
}

TEST_F(PointsIoTest, CsvRaggedRowNamesRowAndCounts) {
  const std::string path = Write("r.csv", "x,y,z\n\n1,2,3\n4,5,6\n7,8\n");
  absl::StatusOr<PointSet> points = ReadPointsFile(path, {});
  ExpectInvalid(points, "row 5 has 2 fields but row 3 (the first data row) has 3");
  EXPECT_THAT(std::string(points.status().message()), StartsWith(path + ": "));
  ExpectInvalid(DecodePointsText("1 2\n3 4 5\n"),
                "row 2 has 3 fields but row 1 (the first data row) has 2");
  // A trailing comma is an empty field, not a shorter row.
  ExpectInvalid(DecodePointsText("1,2\n3,4,\n"), "row 2 has 3 fields");
}

TEST_F(PointsIoTest, CsvNonNumericFieldNamesRowAndColumn) {
  ExpectInvalid(DecodePointsText("x,y\n1,2\n3,abc\n"), "row 3 column 2: 'abc' is not a number");
  // Only the first line can be a header.
  ExpectInvalid(DecodePointsText("x,y\n1,2\nx,y\n"), "row 3 column 1: 'x' is not a number");
  // A first line with a number in it is data with a typo, not a header.
  ExpectInvalid(DecodePointsText("1,2q,3\n4,5,6\n"), "row 1 column 2: '2q' is not a number");
  ExpectInvalid(DecodePointsText("1,,3\n"), "row 1 column 2 is empty");
  ExpectInvalid(DecodePointsText("1,2\n3,0x10\n"), "row 2 column 2: '0x10' is not a number");
  ExpectInvalid(DecodePointsText("1,2\n3,+-4\n"), "row 2 column 2: '+-4' is not a number");
  ExpectInvalid(DecodePointsText("1,2\n3,4\x01\n"), "row 2 column 2: '4\\x01' is not a number");
  ExpectInvalid(DecodePointsText("x,y\n"), "no data rows");
  ExpectInvalid(DecodePointsText("\n\n"), "no data rows");
}

TEST_F(PointsIoTest, CsvNonFiniteValuesNameRowAndColumn) {
  ExpectInvalid(ReadPointsFile(Write("n.csv", "a,b,c\n1,2,3\n4,nan,6\n"), {}),
                "n.csv: row 3 column 2: 'nan' is not finite");
  ExpectInvalid(DecodePointsText("1 2\n3 -inf\n"), "row 2 column 2: '-inf' is not finite");
  ExpectInvalid(DecodePointsText("1,1e39\n"), "row 1 column 2: '1e39' overflows float32");
}

TEST_F(PointsIoTest, TextLimitsAndDims) {
  PointReadOptions options;
  options.limits.max_dims = 2;
  ExpectInvalid(DecodePointsText("1,2,3\n", options),
                "row 1 has 3 fields, over the limit of 2 dimensions");
  options = {};
  options.limits.max_values = 5;
  ExpectInvalid(DecodePointsText("1,2\n3,4\n5,6\n", options),
                "row 3: more than 5 values, the limit");
  options = {};
  options.dims = 3;
  ExpectInvalid(DecodePointsText("1,2\n", options), "d = 2 dimensions but --dims 3 was given");
  options.dims = 2;
  EXPECT_TRUE(DecodePointsText("1,2\n", options).ok());
}

// ---------------------------------------------------------------------------------------
// Raw float32.

TEST_F(PointsIoTest, RawFloat32NeedsDims) {
  const std::string data = Float32Bytes({1, 2, 3, 4, 5, 6});
  PointReadOptions options;
  options.dims = 3;
  for (const std::string name : {"p.f32", "p.bin", "p.raw", "P.F32"}) {
    absl::StatusOr<PointSet> points = ReadPointsFile(Write(name, data), options);
    ASSERT_TRUE(points.ok()) << name << ": " << points.status();
    EXPECT_EQ(points->dims, 3u);
    EXPECT_THAT(points->values, ElementsAre(1, 2, 3, 4, 5, 6));
  }
  options.dims = 2;
  absl::StatusOr<PointSet> points = ReadPointsFile(Path("p.f32"), options);
  ASSERT_TRUE(points.ok()) << points.status();
  EXPECT_EQ(points->num_points(), 3u);

  ExpectInvalid(ReadPointsFile(Path("p.f32"), {}),
                "p.f32: raw float32 does not record the "
                "number of dimensions: give it with --dims");
  options.dims = 4;
  ExpectInvalid(ReadPointsFile(Path("p.f32"), options),
                "24 bytes is not a whole number of 4-dimensional float32 points (16 bytes each)");
  ExpectInvalid(ReadPointsFile(Write("e.f32", ""), options), "m = 0 points");
  options.dims = 1;
  ExpectInvalid(ReadPointsFile(Write("n.bin", Float32Bytes({1, INFINITY})), options),
                "point 1 coordinate 0 is inf");
  options.dims = 2;
  ExpectInvalid(ReadPointsFile(Write("npy.bin", NpyFile(kDict23, data)), options),
                "starts with the .npy magic");
}

// ---------------------------------------------------------------------------------------
// Files.

TEST_F(PointsIoTest, MissingFileIsNotFound) {
  for (const std::string name : {"missing.npy", "missing.csv", "missing.f32", "missing.xyz"}) {
    absl::StatusOr<PointSet> points = ReadPointsFile(Path(name), {});
    ASSERT_FALSE(points.ok()) << name;
    EXPECT_EQ(points.status().code(), absl::StatusCode::kNotFound) << points.status();
    EXPECT_THAT(std::string(points.status().message()), HasSubstr(name));
  }
}

TEST_F(PointsIoTest, UnknownExtensionAndDirectoriesAreRefused) {
  ExpectInvalid(ReadPointsFile(Write("p.xyz", "1 2 3\n"), {}),
                "unknown point file extension '.xyz'");
  std::filesystem::create_directories(Path("dir.npy"));
  ExpectInvalid(ReadPointsFile(Path("dir.npy"), {}), "dir.npy: not a regular file");
}

}  // namespace
}  // namespace mlclust
