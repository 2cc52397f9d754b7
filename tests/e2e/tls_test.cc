// TLS, client certificates and bearer tokens over loopback: the right credentials work;
// plaintext, no token, a wrong token and another tenant's job are refused with the right
// codes; tenants see only their own jobs; the per-tenant job limit. Certificates are made
// at test time with openssl (scripts/install-deps.sh).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <thread>

#include "absl/strings/str_replace.h"
#include "client/client.h"
#include "core/io/draco_codec.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "grpcpp/generic/generic_stub.h"
#include "grpcpp/grpcpp.h"
#include "mlclust/v1/mlclust.grpc.pb.h"
#include "server/server.h"
#include "tests/fixtures/files.h"
#include "tests/fixtures/test_meshes.h"
#include "tests/fixtures/test_server.h"

namespace mlclust {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

constexpr char kAlphaToken[] = "alpha-token-0123456789abcdef";
constexpr char kBetaToken[] = "beta-token-0123456789abcdef";

void WriteText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

// A self-signed server certificate for 127.0.0.1 and localhost, and a CA with one client
// certificate it signed, in a fresh directory.
class Certificates {
 public:
  Certificates() {
    dir_ = std::filesystem::temp_directory_path() /
           ("mlclust_tls_" + std::to_string(::getpid()) + "_" + std::to_string(counter_++));
    std::filesystem::create_directories(dir_);
    const std::string d = dir_.string();
    const std::string quiet = " > /dev/null 2>&1";
    ok_ = std::system(("cd " + d +
                       " && openssl req -x509 -newkey rsa:2048 -nodes -keyout server.key "
                       "-out server.pem -days 1 -subj /CN=localhost "
                       "-addext subjectAltName=DNS:localhost,IP:127.0.0.1" +
                       quiet +
                       " && openssl req -x509 -newkey rsa:2048 -nodes -keyout ca.key -out ca.pem "
                       "-days 1 -subj /CN=mlclust-test-ca" +
                       quiet +
                       " && openssl req -newkey rsa:2048 -nodes -keyout client.key -out client.csr "
                       "-subj /CN=client" +
                       quiet +
                       " && openssl x509 -req -in client.csr -CA ca.pem -CAkey ca.key "
                       "-CAcreateserial -out client.pem -days 1" +
                       quiet)
                          .c_str()) == 0;
    WriteText(path("alpha.token"), std::string(kAlphaToken) + "\n");
    WriteText(path("beta.token"), std::string("# beta\n") + kBetaToken + "\n");
    WriteText(path("wrong.token"), "wrong-token-0123456789abcdef\n");
  }
  ~Certificates() { std::filesystem::remove_all(dir_); }

  bool ok() const { return ok_; }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string pem(const std::string& name) const { return testing::ReadFileBytes(path(name)); }

 private:
  static inline int counter_ = 0;
  std::filesystem::path dir_;
  bool ok_ = false;
};

std::unique_ptr<server::Server> StartTlsServer(const Certificates& certs, bool tokens,
                                               bool client_certs, uint32_t per_tenant = 0) {
  server::ServerOptions options;
  options.gpu = server::GpuMode::kOff;
  options.tls_cert_pem = certs.pem("server.pem");
  options.tls_key_pem = certs.pem("server.key");
  if (client_certs) options.tls_client_ca_pem = certs.pem("ca.pem");
  if (tokens) options.auth_tokens = {{kAlphaToken, "alpha"}, {kBetaToken, "beta"}};
  options.max_jobs_per_tenant = per_tenant;
  absl::StatusOr<std::unique_ptr<server::Server>> started = testing::StartLocal(options);
  EXPECT_TRUE(started.ok()) << started.status();
  return started.ok() ? *std::move(started) : nullptr;
}

std::shared_ptr<grpc::Channel> Channel(const server::Server& server, const Certificates& certs,
                                       const std::string& token_file, bool client_cert = false) {
  client::ConnectOptions options;
  options.tls_ca_file = certs.path("server.pem");
  if (!token_file.empty()) options.auth_token_file = certs.path(token_file);
  if (client_cert) {
    options.tls_cert_file = certs.path("client.pem");
    options.tls_key_file = certs.path("client.key");
  }
  absl::StatusOr<std::shared_ptr<grpc::Channel>> channel =
      client::Connect(absl::StrCat("127.0.0.1:", server.port()), options);
  EXPECT_TRUE(channel.ok()) << channel.status();
  return *channel;
}

v1::JobSpec MeshSpec(v1::Algorithm algorithm = v1::ALGORITHM_HC) {
  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_DRACO_MESH);
  spec.set_algorithm(algorithm);
  return spec;
}

grpc::Status Stats(const std::shared_ptr<grpc::Channel>& channel) {
  auto stub = v1::Clustering::NewStub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(20));
  v1::Stats stats;
  return stub->GetStats(&context, v1::GetStatsRequest(), &stats);
}

TEST(TlsTest, TokensNameTenantsAndEveryOtherCallIsRefusedWithTheRightCode) {
  Certificates certs;
  ASSERT_TRUE(certs.ok()) << "openssl could not make the test certificates";
  std::unique_ptr<server::Server> server = StartTlsServer(certs, /*tokens=*/true, false);
  ASSERT_TRUE(server);
  const std::string bytes = *EncodeMeshToDraco(testing::Grid(10));
  auto alpha = Channel(*server, certs, "alpha.token");
  auto beta = Channel(*server, certs, "beta.token");

  // The right credentials work, attached and detached; the job belongs to alpha.
  absl::StatusOr<client::JobResult> run = client::RunJob(alpha, MeshSpec(), bytes);
  ASSERT_TRUE(run.ok()) << run.status();
  EXPECT_EQ(run->hierarchy.num_levels(), 200u);
  absl::StatusOr<v1::Accepted> accepted = client::SubmitDetached(alpha, MeshSpec(), bytes);
  ASSERT_TRUE(accepted.ok()) << accepted.status();
  EXPECT_EQ(accepted->tenant(), "alpha");
  absl::StatusOr<client::JobResult> watched = client::WatchJob(alpha, accepted->job_id());
  ASSERT_TRUE(watched.ok()) << watched.status();
  EXPECT_EQ(watched->hierarchy.num_levels(), 200u);

  // Another tenant's job: for watch and cancel exactly what an id never issued gets (so a
  // tenant cannot count others' jobs), and absent from its list.
  const std::string never_issued = "job-00000000000000000000000000000000";
  for (const auto& call : {+[](const std::shared_ptr<grpc::Channel>&channel, const std::string&id) {
                             return client::WatchJob(channel, id).status();
                           },
                           +[](const std::shared_ptr<grpc::Channel>&channel, const std::string&id) {
                             return client::CancelJob(channel, id).status();
                           }}) {
    const absl::Status others = call(beta, accepted->job_id());
    const absl::Status unknown = call(beta, never_issued);
    EXPECT_EQ(others.code(), absl::StatusCode::kNotFound);
    EXPECT_EQ(others.code(), unknown.code());
    EXPECT_EQ(others.message(),
              absl::StrReplaceAll(unknown.message(), {{never_issued, accepted->job_id()}}));
  }
  absl::StatusOr<v1::JobList> beta_jobs = client::ListJobs(beta);
  ASSERT_TRUE(beta_jobs.ok()) << beta_jobs.status();
  EXPECT_EQ(beta_jobs->jobs_size(), 0);
  absl::StatusOr<v1::JobList> alpha_jobs = client::ListJobs(alpha);
  ASSERT_TRUE(alpha_jobs.ok());
  ASSERT_EQ(alpha_jobs->jobs_size(), 2);
  EXPECT_EQ(alpha_jobs->jobs(1).tenant(), "alpha");

  // TLS without a token: UNAUTHENTICATED for every Clustering call; health needs none.
  auto anonymous = Channel(*server, certs, "");
  absl::StatusOr<client::JobResult> no_token = client::RunJob(anonymous, MeshSpec(), bytes);
  EXPECT_EQ(no_token.status().code(), absl::StatusCode::kUnauthenticated);
  EXPECT_THAT(no_token.status().message(), HasSubstr("bearer token"));
  EXPECT_EQ(Stats(anonymous).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(client::ListJobs(anonymous).status().code(), absl::StatusCode::kUnauthenticated);
  EXPECT_EQ(client::WatchJob(anonymous, accepted->job_id()).status().code(),
            absl::StatusCode::kUnauthenticated);
  {
    auto health = grpc::health::v1::Health::NewStub(anonymous);
    grpc::ClientContext context;
    grpc::health::v1::HealthCheckRequest request;
    request.set_service("mlclust.v1.Clustering");
    grpc::health::v1::HealthCheckResponse response;
    ASSERT_TRUE(health->Check(&context, request, &response).ok());
    EXPECT_EQ(response.status(), grpc::health::v1::HealthCheckResponse::SERVING);
  }

  // A wrong token: UNAUTHENTICATED, and the message does not repeat it.
  auto wrong = Channel(*server, certs, "wrong.token");
  const grpc::Status wrong_status = Stats(wrong);
  EXPECT_EQ(wrong_status.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_THAT(wrong_status.error_message(), Not(HasSubstr("wrong-token")));
  EXPECT_EQ(client::RunJob(wrong, MeshSpec(), bytes).status().code(),
            absl::StatusCode::kUnauthenticated);

  // The tenant is per call, not per connection: one TLS connection, three calls.
  {
    auto stub = v1::Clustering::NewStub(anonymous);
    for (const char* token : {kBetaToken, kAlphaToken, ""}) {
      grpc::ClientContext context;
      if (*token != '\0') context.set_credentials(grpc::AccessTokenCredentials(token));
      v1::JobList list;
      const grpc::Status status = stub->ListJobs(&context, v1::ListJobsRequest(), &list);
      if (*token == '\0') {
        EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED);
      } else {
        ASSERT_TRUE(status.ok()) << status.error_message();
        EXPECT_EQ(list.jobs_size(), token == kAlphaToken ? 2 : 0);
      }
    }
  }

  // Plaintext to the TLS port: refused (UNAVAILABLE: no TLS handshake, no call).
  auto plaintext = client::Connect(absl::StrCat("127.0.0.1:", server->port()));
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
  v1::Stats stats;
  EXPECT_EQ(v1::Clustering::NewStub(plaintext)
                ->GetStats(&context, v1::GetStatsRequest(), &stats)
                .error_code(),
            grpc::StatusCode::UNAVAILABLE);
  // The client never sends a token in plaintext.
  client::ConnectOptions token_without_tls;
  token_without_tls.auth_token_file = certs.path("alpha.token");
  EXPECT_EQ(client::Connect("127.0.0.1:1", token_without_tls).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(TlsTest, ClientCertificatesAreRequiredWhenTheServerHasAClientCa) {
  Certificates certs;
  ASSERT_TRUE(certs.ok());
  std::unique_ptr<server::Server> server = StartTlsServer(certs, /*tokens=*/false, true);
  ASSERT_TRUE(server);
  EXPECT_TRUE(Stats(Channel(*server, certs, "", /*client_cert=*/true)).ok());
  EXPECT_EQ(Stats(Channel(*server, certs, "", /*client_cert=*/false)).error_code(),
            grpc::StatusCode::UNAVAILABLE);
}

TEST(TlsTest, PerTenantJobLimitRefusesOnlyThatTenant) {
  Certificates certs;
  ASSERT_TRUE(certs.ok());
  std::unique_ptr<server::Server> server = StartTlsServer(certs, true, false, /*per_tenant=*/1);
  ASSERT_TRUE(server);
  auto alpha = Channel(*server, certs, "alpha.token");
  auto beta = Channel(*server, certs, "beta.token");
  absl::StatusOr<v1::Accepted> long_job = client::SubmitDetached(
      alpha, MeshSpec(v1::ALGORITHM_ML), *EncodeMeshToDraco(testing::Grid(250)));
  ASSERT_TRUE(long_job.ok()) << long_job.status();
  const std::string small = *EncodeMeshToDraco(testing::Grid(5));
  absl::StatusOr<client::JobResult> second = client::RunJob(alpha, MeshSpec(), small);
  EXPECT_EQ(second.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(second.status().message(), HasSubstr("tenant 'alpha'"));
  // Beta is not limited by alpha's job (it waits behind it on the one worker).
  EXPECT_TRUE(client::RunJob(beta, MeshSpec(), small).ok());
  ASSERT_TRUE(client::CancelJob(alpha, long_job->job_id()).ok());
}

TEST(TlsTest, TheServerRefusesTokensWithoutTls) {
  server::ServerOptions options;
  options.gpu = server::GpuMode::kOff;
  options.auth_tokens = {{kAlphaToken, "alpha"}};
  absl::StatusOr<std::unique_ptr<server::Server>> started = testing::StartLocal(options);
  EXPECT_EQ(started.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(started.status().message(), HasSubstr("need TLS"));
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

// Issue 24, item 1: one tenant's stalled calls cannot take every slot of the address that
// tenants share (a proxy, one host): calls in progress are also counted per tenant.
TEST(TlsTest, OneTenantsStalledCallsLeaveTheOtherTenantsSlots) {
  Certificates certs;
  ASSERT_TRUE(certs.ok());
  server::ServerOptions options;
  options.gpu = server::GpuMode::kOff;
  options.tls_cert_pem = certs.pem("server.pem");
  options.tls_key_pem = certs.pem("server.key");
  options.auth_tokens = {{kAlphaToken, "alpha"}, {kBetaToken, "beta"}};
  options.max_calls_per_tenant = 2;
  absl::StatusOr<std::unique_ptr<server::Server>> server = testing::StartLocal(options);
  ASSERT_TRUE(server.ok()) << server.status();
  auto alpha = Channel(**server, certs, "alpha.token");
  auto beta = Channel(**server, certs, "beta.token");
  auto stub = v1::Clustering::NewStub(alpha);
  struct Stalled {
    grpc::ClientContext context;
    std::unique_ptr<grpc::ClientReaderWriter<v1::RunRequest, v1::JobEvent>> stream;
  };
  std::vector<std::unique_ptr<Stalled>> stalled;
  for (int i = 0; i < 2; ++i) {
    auto call = std::make_unique<Stalled>();
    call->context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
    call->stream = stub->Run(&call->context);
    v1::RunRequest request;
    *request.mutable_spec() = MeshSpec();
    request.mutable_spec()->set_input_bytes(1 << 20);
    request.set_chunk("x");
    ASSERT_TRUE(call->stream->Write(request));
    stalled.push_back(std::move(call));
    // Admitted before the next one starts (calls started together arrive in any order).
    for (int wait = 0; wait < 1000; ++wait) {
      auto stats_stub = v1::Clustering::NewStub(beta);
      grpc::ClientContext context;
      v1::Stats stats;
      ASSERT_TRUE(stats_stub->GetStats(&context, v1::GetStatsRequest(), &stats).ok());
      if (stats.calls_active() > static_cast<uint32_t>(i)) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  const std::string small = *EncodeMeshToDraco(testing::Grid(5));
  absl::StatusOr<client::JobResult> third = client::RunJob(alpha, MeshSpec(), small);
  EXPECT_EQ(third.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_THAT(third.status().message(), HasSubstr("tenant 'alpha' has 2 calls in progress"));
  EXPECT_TRUE(client::RunJob(beta, MeshSpec(), small).ok());
  for (auto& call : stalled) call->context.TryCancel();
  for (auto& call : stalled) {
    v1::JobEvent event;
    while (call->stream->Read(&event)) {
    }
    call->stream->Finish();
  }
}

}  // namespace
}  // namespace mlclust

namespace mlclust {
namespace {

// A unary call of `method` with an empty message through the generic stub: its status.
grpc::Status GenericCall(const std::shared_ptr<grpc::Channel>& channel, const std::string& method) {
  grpc::GenericStub stub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(20));
  grpc::Slice empty("");  // an empty message (a ByteBuffer without slices is none)
  grpc::ByteBuffer request(&empty, 1), response;
  std::promise<grpc::Status> done;
  stub.UnaryCall(&context, method, grpc::StubOptions(), &request, &response,
                 [&done](grpc::Status status) { done.set_value(std::move(status)); });
  return done.get_future().get();
}

// Issue 24, item 5: server reflection answered without a token on a server that requires
// tokens (it lists the whole API). Now only health checks pass without one.
TEST(TlsTest, ReflectionNeedsATokenWhereTokensAreOn) {
  Certificates certs;
  ASSERT_TRUE(certs.ok());
  std::unique_ptr<server::Server> server = StartTlsServer(certs, /*tokens=*/true, false);
  ASSERT_TRUE(server);
  const std::string reflection = "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo";
  const grpc::Status anonymous = GenericCall(Channel(*server, certs, ""), reflection);
  EXPECT_EQ(anonymous.error_code(), grpc::StatusCode::UNAUTHENTICATED) << anonymous.error_message();
  EXPECT_THAT(anonymous.error_message(), HasSubstr("bearer token"));
  const grpc::Status with_token = GenericCall(Channel(*server, certs, "alpha.token"), reflection);
  EXPECT_NE(with_token.error_code(), grpc::StatusCode::UNAUTHENTICATED)
      << with_token.error_message();
  // Health checks still need none.
  const grpc::Status health =
      GenericCall(Channel(*server, certs, ""), "/grpc.health.v1.Health/Check");
  EXPECT_TRUE(health.ok()) << health.error_message();
}

}  // namespace
}  // namespace mlclust
