// The GL context's memory gauge (mlclust_gpu_memory_bytes): every storage buffer counts
// while it lives, moves do not count twice, the peak stays; the device's memory is reported
// only where the driver exposes it (not on llvmpipe).
#include <gtest/gtest.h>

#include <cstdio>
#include <optional>
#include <utility>
#include <vector>

#include "absl/strings/match.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {
namespace {

TEST(GpuMemoryTest, StorageBuffersCountWhileTheyLive) {
  absl::StatusOr<std::unique_ptr<GlContext>> created = GlContext::Create();
  ASSERT_TRUE(created.ok()) << created.status();
  GlContext& context = **created;
  const std::shared_ptr<GpuMemoryGauge> gauge = context.memory_gauge();
  ASSERT_NE(gauge, nullptr);
  EXPECT_EQ(gauge->buffer_bytes.load(), 0u);
  {
    absl::StatusOr<StorageBuffer> first = StorageBuffer::Create(context, 4096);
    ASSERT_TRUE(first.ok()) << first.status();
    EXPECT_EQ(gauge->buffer_bytes.load(), 4096u);
    absl::StatusOr<StorageBuffer> second = StorageBuffer::Create(context, 1000);
    ASSERT_TRUE(second.ok()) << second.status();
    EXPECT_EQ(gauge->buffer_bytes.load(), 5096u);
    // A move hands the bytes over; assigning over a buffer frees the old one's.
    StorageBuffer moved = *std::move(first);
    EXPECT_EQ(gauge->buffer_bytes.load(), 5096u);
    moved = *std::move(second);
    EXPECT_EQ(gauge->buffer_bytes.load(), 1000u);
    EXPECT_EQ(moved.bytes(), 1000u);
  }
  EXPECT_EQ(gauge->buffer_bytes.load(), 0u);
  EXPECT_EQ(gauge->peak_buffer_bytes.load(), 5096u);
  // A buffer the driver refuses (over the context's limit) counts nothing.
  EXPECT_FALSE(
      StorageBuffer::Create(context, static_cast<uint64_t>(context.max_storage_buffer_bytes()) + 1)
          .ok());
  EXPECT_EQ(gauge->buffer_bytes.load(), 0u);
  // The gauge outlives the context (the server's metrics may hold it).
  created->reset();
  EXPECT_EQ(gauge->peak_buffer_bytes.load(), 5096u);
}

TEST(GpuMemoryTest, TheDevicesMemoryOnlyWhereTheDriverExposesIt) {
  absl::StatusOr<std::unique_ptr<GlContext>> created = GlContext::Create();
  ASSERT_TRUE(created.ok()) << created.status();
  GlContext& context = **created;
  const std::optional<DeviceMemory> memory = context.QueryDeviceMemory();
  if (absl::StrContains(context.renderer(), "llvmpipe")) {
    // Mesa's software renderer has neither GL_NVX_gpu_memory_info nor GL_ATI_meminfo.
    EXPECT_FALSE(memory.has_value()) << memory->source;
    return;
  }
  if (!memory.has_value()) return;  // a driver without either extension
  std::printf("device memory (%s): total %llu, available %llu bytes\n", memory->source.c_str(),
              static_cast<unsigned long long>(memory->total_bytes),
              static_cast<unsigned long long>(memory->available_bytes));
  EXPECT_GT(memory->available_bytes, 0u);
  if (memory->source == "GL_NVX_gpu_memory_info") {
    EXPECT_GE(memory->total_bytes, memory->available_bytes);
    // A 64 MiB buffer shows in the driver's free memory (NVIDIA reports it at once).
    const uint64_t before = memory->available_bytes;
    absl::StatusOr<StorageBuffer> buffer = StorageBuffer::Create(context, uint64_t{64} << 20);
    ASSERT_TRUE(buffer.ok()) << buffer.status();
    std::vector<uint8_t> zeros(uint64_t{64} << 20);
    ASSERT_TRUE(buffer->Upload(0, zeros.data(), zeros.size()).ok());
    const std::optional<DeviceMemory> after = context.QueryDeviceMemory();
    ASSERT_TRUE(after.has_value());
    std::printf("after a 64 MiB buffer: available %llu bytes (%lld less)\n",
                static_cast<unsigned long long>(after->available_bytes),
                static_cast<long long>(before) - static_cast<long long>(after->available_bytes));
  }
}

}  // namespace
}  // namespace mlclust::gpu
