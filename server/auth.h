// Bearer tokens: each names a tenant. The server's AuthMetadataProcessor checks the
// `authorization: Bearer TOKEN` header of every call on a TLS listener; the Clustering
// service then serves the call as that tenant (jobs are visible only to their tenant) and
// refuses calls without a token. Health checks and reflection need none (probes).
//
// The tenant is looked up per call (TenantOfCall), not stored in the auth context: gRPC
// shares an AuthContext's added properties among all calls of a connection, so a tenant
// added there would leak to the connection's later calls, with another token or none
// (tests/e2e/tls_test.cc caught it).
//
// No token is ever logged or put in a message: errors name the line of the token file,
// never its text.
#ifndef MLCLUST_SERVER_AUTH_H_
#define MLCLUST_SERVER_AUTH_H_

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "grpcpp/security/auth_metadata_processor.h"

namespace mlclust::server {

// Token -> tenant, from a token file: one "TOKEN TENANT" per line (blank lines and lines
// starting with '#' skipped). INVALID_ARGUMENT naming the line for a line without a tenant,
// a token shorter than 16 characters, or a token given twice.
absl::StatusOr<std::map<std::string, std::string>> ParseTokenFile(const std::string& text);

// Checks the bearer token of each call: an unknown one, or an authorization header that
// is not "Bearer TOKEN", is refused with UNAUTHENTICATED; a known one, or none, passes (the
// service refuses calls without one, the health service does not).
std::shared_ptr<grpc::AuthMetadataProcessor> MakeTokenProcessor(
    std::map<std::string, std::string> tokens);

// The tenant of a call from its `authorization` header value ("" when the call has none):
// UNAUTHENTICATED when it has none or an unknown one.
absl::StatusOr<std::string> TenantOfCall(const std::map<std::string, std::string>& tokens,
                                         std::optional<std::string_view> authorization);

}  // namespace mlclust::server

#endif  // MLCLUST_SERVER_AUTH_H_
