#include "server/auth.h"

#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"

namespace mlclust::server {
namespace {

constexpr size_t kMinTokenLength = 16;

class TokenProcessor : public grpc::AuthMetadataProcessor {
 public:
  explicit TokenProcessor(std::map<std::string, std::string> tokens) : tokens_(std::move(tokens)) {}

  // A map lookup: no need for another thread.
  bool IsBlocking() const override { return false; }

  grpc::Status Process(const InputMetadata& auth_metadata, grpc::AuthContext* context,
                       OutputMetadata* consumed_auth_metadata,
                       OutputMetadata* response_metadata) override {
    auto header = auth_metadata.find("authorization");
    if (header == auth_metadata.end()) {
      // Without a token only health checks pass (load balancers probe without one); the
      // Clustering service answers its own calls (UNAUTHENTICATED with a message), and
      // everything else (server reflection, which lists the API) is refused here.
      auto path = auth_metadata.find(":path");
      const std::string_view method =
          path == auth_metadata.end() ? std::string_view()
                                      : std::string_view(path->second.data(), path->second.size());
      if (method.starts_with("/grpc.health.v1.Health/") ||
          method.starts_with("/mlclust.v1.Clustering/")) {
        return grpc::Status::OK;
      }
      return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                          "this server needs a bearer token (mlclust --auth-token-file FILE, "
                          "over TLS) for every service but health checks");
    }
    absl::StatusOr<std::string> tenant =
        TenantOfCall(tokens_, std::string_view(header->second.data(), header->second.size()));
    if (!tenant.ok()) {
      return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                          std::string(tenant.status().message()));
    }
    return grpc::Status::OK;
  }

 private:
  const std::map<std::string, std::string> tokens_;
};

}  // namespace

absl::StatusOr<std::string> TenantOfCall(const std::map<std::string, std::string>& tokens,
                                         std::optional<std::string_view> authorization) {
  if (!authorization.has_value()) {
    return absl::UnauthenticatedError(
        "this server needs a bearer token (mlclust --auth-token-file FILE, over TLS)");
  }
  constexpr std::string_view kBearer = "Bearer ";
  if (authorization->substr(0, kBearer.size()) != kBearer) {
    return absl::UnauthenticatedError("the authorization header is not 'Bearer TOKEN'");
  }
  auto tenant = tokens.find(std::string(authorization->substr(kBearer.size())));
  if (tenant == tokens.end()) {
    return absl::UnauthenticatedError("the bearer token is not one this server knows");
  }
  return tenant->second;
}

absl::StatusOr<std::map<std::string, std::string>> ParseTokenFile(const std::string& text) {
  std::map<std::string, std::string> tokens;
  int line_number = 0;
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    ++line_number;
    line = absl::StripAsciiWhitespace(line);
    if (line.empty() || line.front() == '#') continue;
    std::vector<std::string> words =
        absl::StrSplit(line, absl::ByAnyChar(" \t"), absl::SkipEmpty());
    if (words.size() != 2) {
      return absl::InvalidArgumentError(
          absl::StrCat("token file line ", line_number,
                       ": expected 'TOKEN TENANT' (two words), found ", words.size()));
    }
    if (words[0].size() < kMinTokenLength) {
      return absl::InvalidArgumentError(absl::StrCat("token file line ", line_number,
                                                     ": the token is shorter than ",
                                                     kMinTokenLength, " characters"));
    }
    if (!tokens.emplace(words[0], words[1]).second) {
      return absl::InvalidArgumentError(
          absl::StrCat("token file line ", line_number, ": a token given twice"));
    }
  }
  if (tokens.empty()) return absl::InvalidArgumentError("the token file holds no token");
  return tokens;
}

std::shared_ptr<grpc::AuthMetadataProcessor> MakeTokenProcessor(
    std::map<std::string, std::string> tokens) {
  return std::make_shared<TokenProcessor>(std::move(tokens));
}

}  // namespace mlclust::server
