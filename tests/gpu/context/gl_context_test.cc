#include "gpu/context/gl_context.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <thread>

#include "absl/strings/match.h"

namespace mlclust::gpu {
namespace {

// CI runs on Mesa's llvmpipe; GPU nodes on NVIDIA. Both must give a 4.5 core context.
TEST(GpuContextTest, CreatesAnOpenGl45CoreContext) {
  absl::StatusOr<std::unique_ptr<GlContext>> context = GlContext::Create();
  ASSERT_TRUE(context.ok()) << context.status();
  const GlContext& gl = **context;
  std::printf("EGL device: %s\nrenderer: %s\nvendor: %s\nversion: %s\n",
              gl.device_description().c_str(), gl.renderer().c_str(), gl.vendor().c_str(),
              gl.version().c_str());
  EXPECT_FALSE(gl.renderer().empty());
  EXPECT_FALSE(gl.vendor().empty());
  EXPECT_FALSE(gl.device_description().empty());
  EXPECT_TRUE(gl.major_version() > 4 || (gl.major_version() == 4 && gl.minor_version() >= 5))
      << gl.version();
  EXPECT_TRUE(absl::StrContains(gl.version(), "Core Profile") || !gl.is_software())
      << "Mesa names the profile in GL_VERSION: " << gl.version();
  // Without a GPU the only device is Mesa's software one, and its renderer is llvmpipe.
  if (gl.is_software()) {
    EXPECT_TRUE(absl::StrContains(gl.renderer(), "llvmpipe")) << gl.renderer();
  }
  EXPECT_GE(gl.max_work_groups(0), 65535u);  // the GL 4.3 minimum
  EXPECT_GE(gl.max_work_groups(1), 65535u);
  EXPECT_GE(gl.max_storage_buffer_bytes(), int64_t{1} << 24);
}

TEST(GpuContextTest, OptionsCapTheLimits) {
  GlContextOptions options;
  options.max_groups_per_dimension = 3;
  options.max_storage_buffer_bytes = 4096;
  absl::StatusOr<std::unique_ptr<GlContext>> context = GlContext::Create(options);
  ASSERT_TRUE(context.ok()) << context.status();
  EXPECT_EQ((*context)->max_work_groups(0), 3u);
  EXPECT_EQ((*context)->max_work_groups(1), 3u);
  EXPECT_EQ((*context)->max_storage_buffer_bytes(), 4096);
}

TEST(GpuContextTest, RejectsBadOptions) {
  GlContextOptions no_groups;
  no_groups.max_groups_per_dimension = 0;
  EXPECT_EQ(GlContext::Create(no_groups).status().code(), absl::StatusCode::kInvalidArgument);

  GlContextOptions negative_bytes;
  negative_bytes.max_storage_buffer_bytes = -1;
  EXPECT_EQ(GlContext::Create(negative_bytes).status().code(), absl::StatusCode::kInvalidArgument);

  GlContextOptions no_such_device;
  no_such_device.device_index = 1000;
  EXPECT_EQ(GlContext::Create(no_such_device).status().code(), absl::StatusCode::kInvalidArgument);
}

// A machine without a GPU has nothing to offer once software is refused; a GPU node does.
TEST(GpuContextTest, HardwareOnlyIsUnavailableOrHardware) {
  GlContextOptions options;
  options.allow_software = false;
  absl::StatusOr<std::unique_ptr<GlContext>> context = GlContext::Create(options);
  if (context.ok()) {
    EXPECT_FALSE((*context)->is_software()) << (*context)->renderer();
  } else {
    EXPECT_EQ(context.status().code(), absl::StatusCode::kUnavailable) << context.status();
    std::printf("no hardware device: %s\n", context.status().ToString().c_str());
  }
}

TEST(GpuContextTest, ExplicitDeviceIndexUsesThatDevice) {
  absl::StatusOr<std::unique_ptr<GlContext>> context = GlContext::Create();
  ASSERT_TRUE(context.ok()) << context.status();
  if (!absl::StartsWith((*context)->device_description(), "EGL device 0 ")) {
    GTEST_SKIP() << "the automatic choice is not device 0: " << (*context)->device_description();
  }
  context->reset();
  GlContextOptions options;
  options.device_index = 0;
  context = GlContext::Create(options);
  ASSERT_TRUE(context.ok()) << context.status();
  EXPECT_TRUE(absl::StartsWith((*context)->device_description(), "EGL device 0 "));
}

// EGL displays are per device and per process; destroying one context must not terminate
// the display under another one on the same device.
TEST(GpuContextTest, TwoContextsOnOneDeviceAreIndependent) {
  absl::StatusOr<std::unique_ptr<GlContext>> first = GlContext::Create();
  absl::StatusOr<std::unique_ptr<GlContext>> second = GlContext::Create();
  ASSERT_TRUE(first.ok()) << first.status();
  ASSERT_TRUE(second.ok()) << second.status();
  EXPECT_EQ((*first)->device_description(), (*second)->device_description());
  ASSERT_TRUE((*first)->MakeCurrent().ok());
  ASSERT_TRUE((*second)->MakeCurrent().ok());
  first->reset();
  EXPECT_TRUE((*second)->MakeCurrent().ok());
  absl::StatusOr<std::unique_ptr<GlContext>> third = GlContext::Create();
  ASSERT_TRUE(third.ok()) << third.status();
  EXPECT_TRUE((*second)->MakeCurrent().ok());
}

TEST(GpuContextTest, UseFromAnotherThreadIsAFailedPrecondition) {
  absl::StatusOr<std::unique_ptr<GlContext>> context = GlContext::Create();
  ASSERT_TRUE(context.ok()) << context.status();
  absl::Status other_thread_status;
  std::thread([&] { other_thread_status = (*context)->MakeCurrent(); }).join();
  EXPECT_EQ(other_thread_status.code(), absl::StatusCode::kFailedPrecondition)
      << other_thread_status;
  EXPECT_TRUE((*context)->MakeCurrent().ok());
}

}  // namespace
}  // namespace mlclust::gpu
