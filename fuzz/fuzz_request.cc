// A job request as the server decodes it before any clustering: the JobSpec from its wire
// bytes (protobuf), turned into a job plan (algorithm, energy, typed options) by
// PlanWireJob (server/job_options.cc, which needs only core and the messages), and the
// input decoded as spec.input_kind says: a Draco mesh then ValidateMesh, or m x d float32
// points then ValidatePoints. Not covered: the gRPC framing and the server's size and
// queue admission (server/server.cc), which need a running server.
//
// Input: two bytes (little-endian) giving the length n of the JobSpec bytes, the n bytes,
// then the job's input.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "core/io/draco_codec.h"
#include "core/mesh/mesh.h"
#include "core/points/points.h"
#include "fuzz/fuzz_check.h"
#include "mlclust/v1/mlclust.pb.h"
#include "server/job_options.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mlclust;
  if (size < 2) return 0;
  const size_t spec_size = std::min<size_t>(data[0] | (size_t{data[1]} << 8), size - 2);
  v1::JobSpec spec;
  if (!spec.ParseFromArray(data + 2, static_cast<int>(spec_size))) return 0;
  const std::string_view input(reinterpret_cast<const char*>(data) + 2 + spec_size,
                               size - 2 - spec_size);
  absl::StatusOr<JobPlan> plan = server::PlanWireJob(spec);
  if (!plan.ok()) {
    MLCLUST_FUZZ_CHECK(plan.status().code() == absl::StatusCode::kInvalidArgument ||
                       plan.status().code() == absl::StatusCode::kUnimplemented);
    return 0;
  }
  MLCLUST_FUZZ_CHECK(plan->algorithm != nullptr);
  if (spec.input_kind() == v1::INPUT_KIND_DRACO_MESH) {
    absl::StatusOr<TriangleMesh> mesh = DecodeDracoMesh(input);
    if (mesh.ok()) (void)ValidateMesh(*mesh);
  } else if (spec.input_kind() == v1::INPUT_KIND_POINTS_F32) {
    const uint32_t d = spec.point_dims();
    if (d == 0 || input.size() % (size_t{4} * d) != 0) return 0;
    PointSet points;
    points.dims = d;
    points.values.resize(input.size() / 4);
    if (!input.empty()) std::memcpy(points.values.data(), input.data(), input.size());
    (void)ValidatePoints(points);
  }
  return 0;
}
