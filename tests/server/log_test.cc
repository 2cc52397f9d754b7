// Log lines against injection: LogSafe escapes every control character and every byte
// that is not UTF-8 and cuts long values; LogLine and LogEvent put every value through it,
// in text and JSON (each JSON line parses, whatever a client sent).
#include "server/log.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "google/protobuf/struct.pb.h"
#include "google/protobuf/util/json_util.h"
#include "tests/fixtures/capture_stderr.h"

namespace mlclust::server {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

TEST(LogSafeTest, EscapesControlsAnsiC1AndInvalidUtf8) {
  EXPECT_EQ(LogSafe("plain label, ünïcode ✓ 🙂"), "plain label, ünïcode ✓ 🙂");
  EXPECT_EQ(LogSafe("a\nb\r\tc"), "a\\x0ab\\x0d\\x09c");
  EXPECT_EQ(LogSafe("\x1b[31mred\x1b[0m"), "\\x1b[31mred\\x1b[0m");
  EXPECT_EQ(LogSafe(std::string("nul\0del\x7f", 8)), "nul\\x00del\\x7f");
  EXPECT_EQ(LogSafe("c1 \xc2\x9b csi \xc2\x85 nel"), "c1 \\u009b csi \\u0085 nel");
  // Bytes that are not UTF-8: a lone continuation, a cut sequence, an overlong '/', a
  // surrogate.
  EXPECT_EQ(LogSafe("\x80 \xe2\x9c \xc0\xaf \xed\xa0\x80"),
            "\\x80 \\xe2\\x9c \\xc0\\xaf \\xed\\xa0\\x80");
}

TEST(LogSafeTest, CutsLongValuesOnACharacterBoundaryAndSaysHowLong) {
  const std::string big(8 << 20, 'x');
  const std::string safe = LogSafe(big);
  EXPECT_EQ(safe, std::string(kLoggedValueBytes, 'x') + "...[8388608 bytes]");
  std::string accents;
  for (int i = 0; i < 200; ++i) accents += "é";  // 2 bytes each
  const std::string cut = LogSafe(accents, 11);
  EXPECT_EQ(cut, "éééééé...[400 bytes]");
  EXPECT_EQ(LogSafe("short", 5), "short");
}

using testing::CaptureStderr;
using testing::LinesOf;

const std::string kForging =
    "x\n2026-01-01T00:00:00.000Z mlclust: job-1 done in 1s\x1b[2K\xc2\x9b\xff";

TEST(LogLineTest, AClientsValueCannotForgeALineInText) {
  JsonLogs() = false;
  const std::string out = CaptureStderr([] {
    LogLine(true, "accepted (label '", kForging, "')");
    LogEvent("job_accepted").Add("label", kForging).Write(true, "label " + kForging);
    LogLine(true, "big ", std::string(1 << 20, 'y'));
  });
  const std::vector<std::string> lines = LinesOf(out);
  ASSERT_EQ(lines.size(), 3u) << out;
  for (const std::string& line : lines) {
    EXPECT_THAT(line, Not(HasSubstr("\x1b")));
    EXPECT_THAT(line, Not(HasSubstr("\xc2\x9b")));
    EXPECT_THAT(line, ::testing::MatchesRegex("[0-9T:.Z-]+ mlclust: .*"));
    EXPECT_LT(line.size(), kLoggedLineBytes + 64);
  }
  EXPECT_THAT(lines[0], HasSubstr("x\\x0a2026-01-01T00:00:00.000Z mlclust: job-1"));
  EXPECT_THAT(lines[2], HasSubstr("...[1048580 bytes]"));
}

TEST(LogLineTest, EveryJsonLineParsesAndValuesAreCut) {
  JsonLogs() = true;
  const std::string out = CaptureStderr([] {
    LogLine(true, "free text ", kForging);
    LogEvent("job_accepted")
        .Add("label", kForging)
        .Add("tenant", std::string(8 << 20, 't'))
        .Add("message", std::string(8 << 20, 'm'), kLoggedLineBytes)
        .Write(true, "unused in JSON");
  });
  JsonLogs() = false;
  const std::vector<std::string> lines = LinesOf(out);
  ASSERT_EQ(lines.size(), 2u) << out;
  for (const std::string& line : lines) {
    google::protobuf::Struct parsed;
    ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(line, &parsed).ok()) << line;
    EXPECT_THAT(line, Not(HasSubstr("\x1b")));
  }
  google::protobuf::Struct event;
  ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(lines[1], &event).ok());
  EXPECT_EQ(event.fields().at("label").string_value(),
            "x\\x0a2026-01-01T00:00:00.000Z mlclust: job-1 done in 1s\\x1b[2K\\u009b\\xff");
  EXPECT_EQ(event.fields().at("tenant").string_value(),
            std::string(kLoggedValueBytes, 't') + "...[8388608 bytes]");
  EXPECT_EQ(event.fields().at("message").string_value(),
            std::string(kLoggedLineBytes, 'm') + "...[8388608 bytes]");
}

}  // namespace
}  // namespace mlclust::server
