// The token file: "TOKEN TENANT" lines; errors name the line, never the token.
#include "server/auth.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace mlclust::server {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

TEST(TokenFileTest, ReadsTokensAndTenantsSkippingCommentsAndBlankLines) {
  absl::StatusOr<std::map<std::string, std::string>> tokens =
      ParseTokenFile("# pipeline tokens\n\n  aaaaaaaaaaaaaaaa1 studio\t\nbbbbbbbbbbbbbbbb2\tlab\n");
  ASSERT_TRUE(tokens.ok()) << tokens.status();
  EXPECT_EQ(tokens->size(), 2u);
  EXPECT_EQ(tokens->at("aaaaaaaaaaaaaaaa1"), "studio");
  EXPECT_EQ(tokens->at("bbbbbbbbbbbbbbbb2"), "lab");
}

TEST(TokenFileTest, RefusesBadLinesNamingTheLineButNotTheToken) {
  struct Case {
    const char* text;
    const char* message;
  };
  for (const Case& c :
       {Case{"secret-token-without-tenant\n", "line 1: expected 'TOKEN TENANT'"},
        Case{"# x\nshort-secret t\n", "line 2: the token is shorter than 16"},
        Case{"secret-token-0123456 a\nsecret-token-0123456 b\n", "line 2: a token given twice"},
        Case{"secret-token-0123456 a b\n", "line 1: expected"},
        Case{"# nothing\n", "holds no token"}}) {
    absl::StatusOr<std::map<std::string, std::string>> tokens = ParseTokenFile(c.text);
    ASSERT_FALSE(tokens.ok()) << c.text;
    EXPECT_EQ(tokens.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(tokens.status().message(), HasSubstr(c.message));
    EXPECT_THAT(tokens.status().message(), Not(HasSubstr("secret")));
  }
}

}  // namespace
}  // namespace mlclust::server
