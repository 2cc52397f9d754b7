#include "gpu/context/compute.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <numeric>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "gpu/context/gl_context.h"
#include "gpu/context/gl_functions.h"

namespace mlclust::gpu {
namespace {

using ::testing::HasSubstr;

TEST(GpuComputeTest, PreludeMatchesLocalSize) {
  EXPECT_TRUE(
      absl::StrContains(kComputeShaderPrelude, absl::StrCat("local_size_x = ", kLocalSize, ",")));
}

TEST(GpuComputeTest, PlanDispatchUsesOneRowWhenItFits) {
  absl::StatusOr<DispatchGrid> grid = PlanDispatch(1, 65535, 65535);
  ASSERT_TRUE(grid.ok());
  EXPECT_EQ(grid->groups_x, 1u);
  EXPECT_EQ(grid->groups_y, 1u);

  grid = PlanDispatch(uint64_t{65535} * kLocalSize, 65535, 65535);
  ASSERT_TRUE(grid.ok());
  EXPECT_EQ(grid->groups_x, 65535u);
  EXPECT_EQ(grid->groups_y, 1u);

  grid = PlanDispatch(0, 65535, 65535);
  ASSERT_TRUE(grid.ok());
  EXPECT_EQ(grid->groups_x * grid->groups_y, 0u);
}

TEST(GpuComputeTest, PlanDispatchSplitsPastTheRowLimit) {
  // One invocation more than a full row: a second row of 65535 groups (mostly idle).
  absl::StatusOr<DispatchGrid> grid = PlanDispatch(uint64_t{65535} * kLocalSize + 1, 65535, 65535);
  ASSERT_TRUE(grid.ok());
  EXPECT_EQ(grid->groups_x, 65535u);
  EXPECT_EQ(grid->groups_y, 2u);

  grid = PlanDispatch(10 * kLocalSize, 3, 100);
  ASSERT_TRUE(grid.ok());
  EXPECT_EQ(grid->groups_x, 3u);
  EXPECT_EQ(grid->groups_y, 4u);  // 12 groups cover 10
}

TEST(GpuComputeTest, PlanDispatchRejectsWhatDoesNotFit) {
  EXPECT_EQ(PlanDispatch(10 * kLocalSize, 3, 3).status().code(), absl::StatusCode::kOutOfRange);
  EXPECT_EQ(PlanDispatch(uint64_t{1} << 33, 65535, 65535).status().code(),
            absl::StatusCode::kOutOfRange);  // past the 32-bit linear index
  EXPECT_EQ(PlanDispatch(1, 0, 1).status().code(), absl::StatusCode::kInvalidArgument);
}

class GpuComputeContextTest : public ::testing::Test {
 protected:
  void SetUp() override {
    GlContextOptions options;
    // A 3 x 3 grid of 256: small inputs reach the 2-D split.
    options.max_groups_per_dimension = 3;
    options.max_storage_buffer_bytes = 1 << 16;
    absl::StatusOr<std::unique_ptr<GlContext>> context = GlContext::Create(options);
    ASSERT_TRUE(context.ok()) << context.status();
    context_ = *std::move(context);
  }
  std::unique_ptr<GlContext> context_;
};

TEST_F(GpuComputeContextTest, CompileErrorCarriesTheInfoLog) {
  absl::StatusOr<uint32_t> program = CompileComputeProgram(
      *context_, absl::StrCat(kComputeShaderPrelude, "void main() { undeclared_name = 1u; }\n"));
  ASSERT_FALSE(program.ok());
  EXPECT_EQ(program.status().code(), absl::StatusCode::kInternal);
  EXPECT_THAT(std::string(program.status().message()), HasSubstr("undeclared_name"));

  absl::StatusOr<uint32_t> cached =
      GetComputeProgram(*context_, "broken", "#version 450\nthis is not GLSL\n");
  ASSERT_FALSE(cached.ok());
  EXPECT_THAT(std::string(cached.status().message()), HasSubstr("kernel 'broken'"));
}

TEST_F(GpuComputeContextTest, ProgramsAreCachedByName) {
  const std::string source = absl::StrCat(kComputeShaderPrelude, "void main() {}\n");
  absl::StatusOr<uint32_t> first = GetComputeProgram(*context_, "empty", source);
  absl::StatusOr<uint32_t> second = GetComputeProgram(*context_, "empty", source);
  ASSERT_TRUE(first.ok()) << first.status();
  ASSERT_TRUE(second.ok()) << second.status();
  EXPECT_EQ(*first, *second);
}

TEST_F(GpuComputeContextTest, StorageBufferRoundTripAndBounds) {
  std::vector<uint32_t> values(1000);
  std::iota(values.begin(), values.end(), 7u);
  absl::StatusOr<StorageBuffer> buffer =
      StorageBuffer::Create(*context_, values.size() * sizeof(uint32_t));
  ASSERT_TRUE(buffer.ok()) << buffer.status();
  ASSERT_TRUE(buffer->Upload(std::span<const uint32_t>(values)).ok());
  std::vector<uint32_t> back(values.size());
  ASSERT_TRUE(buffer->Download(std::span<uint32_t>(back)).ok());
  EXPECT_EQ(back, values);

  EXPECT_EQ(buffer->Upload(std::span<const uint32_t>(values), 4).code(),
            absl::StatusCode::kOutOfRange);
  EXPECT_EQ(buffer->Download(std::span<uint32_t>(back), 4).code(), absl::StatusCode::kOutOfRange);
  EXPECT_EQ(StorageBuffer::Create(*context_, 0).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(StorageBuffer::Create(*context_, (1 << 16) + 1).status().code(),
            absl::StatusCode::kResourceExhausted);
}

// Every linear index below the count is visited exactly once, and none past it, across
// a grid split into rows.
TEST_F(GpuComputeContextTest, TwoDimensionalDispatchVisitsEachIndexOnce) {
  constexpr absl::string_view kCountVisits = R"glsl(
layout(std430, binding = 0) buffer Visits { uint visits[]; };
layout(location = 0) uniform uint u_count;
void main() {
  uint i = LinearInvocationIndex();
  if (i >= u_count) return;
  atomicAdd(visits[i], 1u);
}
)glsl";
  absl::StatusOr<uint32_t> program = GetComputeProgram(
      *context_, "count_visits", absl::StrCat(kComputeShaderPrelude, kCountVisits));
  ASSERT_TRUE(program.ok()) << program.status();
  // 2,000 invocations: 8 groups, i.e. 3 rows of 3 on this context, the last row partial.
  constexpr uint32_t kCount = 2000;
  std::vector<uint32_t> visits(kCount + 64, 0);
  absl::StatusOr<StorageBuffer> buffer =
      StorageBuffer::Create(*context_, visits.size() * sizeof(uint32_t));
  ASSERT_TRUE(buffer.ok()) << buffer.status();
  ASSERT_TRUE(buffer->Upload(std::span<const uint32_t>(visits)).ok());
  absl::StatusOr<DispatchGrid> grid =
      PlanDispatch(kCount, context_->max_work_groups(0), context_->max_work_groups(1));
  ASSERT_TRUE(grid.ok());
  EXPECT_EQ(grid->groups_x, 3u);
  EXPECT_EQ(grid->groups_y, 3u);

  const detail::GlFunctions& gl = context_->gl();
  gl.UseProgram(*program);
  gl.ProgramUniform1ui(*program, 0, kCount);
  buffer->Bind(0);
  ASSERT_TRUE(DispatchLinear(*context_, kCount).ok());
  ASSERT_TRUE(buffer->Download(std::span<uint32_t>(visits)).ok());
  for (uint32_t i = 0; i < visits.size(); ++i) {
    ASSERT_EQ(visits[i], i < kCount ? 1u : 0u) << "index " << i;
  }
  // Past 3 x 3 groups the dispatch does not fit.
  EXPECT_EQ(DispatchLinear(*context_, 9 * kLocalSize + 1).code(), absl::StatusCode::kOutOfRange);
  EXPECT_EQ(MaxInvocationsPerDispatch(*context_), 9 * kLocalSize);
}

}  // namespace
}  // namespace mlclust::gpu
