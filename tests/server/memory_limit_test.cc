// The memory a server's options need against its cgroup's limit (issue 24, item 8): the
// parts add up as the deployment manifest's comment says, limit files of cgroup v2 and
// v1 are read, "max" and v1's "no limit" mean none, and a configuration that does not fit
// is refused naming every part.
#include "server/memory_limit.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace mlclust::server {
namespace {

using ::testing::HasSubstr;

TEST(MemoryLimitTest, TheManifestsFlagsNeedWhatItsCommentSays) {
  // docker/k8s/base/deployment.yaml: --workers 2, --max-input-mb 64, --max-queued-mb 1024,
  // --max-upload-mb 512, --result-total-mb 1024, --kept-results-mb 1024: 11,968 MiB.
  ServerOptions options;
  options.cpu_workers = 2;
  options.max_input_bytes = uint64_t{64} << 20;
  options.max_queued_input_bytes = uint64_t{1024} << 20;
  options.max_upload_bytes_in_flight = uint64_t{512} << 20;
  options.result_server_budget_bytes = uint64_t{1024} << 20;
  options.kept_results_bytes = uint64_t{1024} << 20;
  const MemoryNeeded needed = MemoryNeededFor(options);
  EXPECT_EQ(needed.running_jobs, uint64_t{7872} << 20);
  EXPECT_EQ(needed.total(), uint64_t{11968} << 20);
  EXPECT_TRUE(CheckMemoryFits(needed, uint64_t{14} << 30).ok());
  EXPECT_TRUE(CheckMemoryFits(needed, std::nullopt).ok());
}

TEST(MemoryLimitTest, ADefaultServersBudgetsDoNotFitFourGibAndItSaysWhy) {
  // Defaults: queued 4096 + uploads 1024 + unread 1024 + kept 1024 + process 512 MiB.
  const MemoryNeeded needed = MemoryNeededFor(ServerOptions{});
  EXPECT_EQ(needed.budgets(), uint64_t{7680} << 20);
  EXPECT_TRUE(CheckMemoryFits(needed, uint64_t{8} << 30).ok());
  EXPECT_FALSE(RunningJobsFit(needed, uint64_t{8} << 30));  // one 1 GiB job: 41 GiB more
  const absl::Status status = CheckMemoryFits(needed, uint64_t{4} << 30);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(status.message(), HasSubstr("take up to 7680 MiB but it is given 4096 MiB"));
  EXPECT_THAT(status.message(), HasSubstr("queued inputs 4096 MiB (--max-queued-mb)"));
  EXPECT_THAT(status.message(), HasSubstr("kept results 1024 MiB (--kept-results-mb)"));
}

TEST(MemoryLimitTest, ReadsCgroupV2AndV1LimitFiles) {
  const std::filesystem::path root =
      std::filesystem::temp_directory_path() / ("mlclust_cgroup_" + std::to_string(::getpid()));
  std::filesystem::remove_all(root);
  std::filesystem::create_directories(root / "memory");
  EXPECT_EQ(CgroupMemoryLimit(root.string()), std::nullopt);  // no files: no limit
  std::ofstream(root / "memory" / "memory.limit_in_bytes") << "9223372036854771712\n";
  EXPECT_EQ(CgroupMemoryLimit(root.string()), std::nullopt);  // v1's "no limit"
  std::ofstream(root / "memory" / "memory.limit_in_bytes") << "4294967296\n";
  EXPECT_EQ(CgroupMemoryLimit(root.string()), uint64_t{4} << 30);
  std::ofstream(root / "memory.max") << "max\n";
  EXPECT_EQ(CgroupMemoryLimit(root.string()), std::nullopt);  // v2 first: "max"
  std::ofstream(root / "memory.max") << "2147483648\n";
  EXPECT_EQ(CgroupMemoryLimit(root.string()), uint64_t{2} << 30);
  std::filesystem::remove_all(root);
}

}  // namespace
}  // namespace mlclust::server
