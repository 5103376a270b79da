// `dvs cache list` and `dvs cache clean` on a cache folder made by hand: entries of known sizes and ages, a
// latent whose metadata is written but whose array is not yet (a store under way), and temporary files of a
// live writer (this test's own process) and of a dead one. Clean removes by age, then the least recently used
// down to the size, and never a file a live process is writing.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>

#include "dvs/cache.hpp"
#include "support/files.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

struct HandMadeCache {
  test::TempDir dir;
  fs::path folder = dir / "c";
  // days: how long ago the entry was last used.
  void put(const std::string& name, size_t bytes, double days) {
    test::write_text(folder / name, std::string(bytes, 'x'));
    fs::last_write_time(folder / name, fs::file_time_type::clock::now() - std::chrono::seconds(int64_t(days * 86400)));
  }
  HandMadeCache() {
    put("depth-00000000000000a1.npy", 1000, 1);
    put("eps_inv-00000000000000b2.npy", 2000, 5);
    put("latent-00000000000000c3.npy", 3000, 10);
    put("latent-00000000000000c3.json", 100, 10);
    put("latent-00000000000000d4.json", 100, 20);  // metadata only: the latent's store is under way
    put("eps_inv-00000000000000e5.npy.tmp-" + std::to_string(::getpid()) + "-0", 500, 30);  // a live writer's
    put("depth-00000000000000f6.npy.tmp-4194305-0", 500, 30);  // pid > PID_MAX_LIMIT: never alive
    put("notes.txt", 10, 40);                                   // not the cache's
  }
  std::string dvs(const std::string& args) const {
    const auto r = test::run_command(test::program("dvs") + " cache " + args + " --cache-dir " + folder.string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return r.output;
  }
};

TEST(CliCache, ListsCompleteEntriesMostRecentlyUsedFirst) {
  HandMadeCache c;
  const auto list = list_cache(c.folder);
  ASSERT_EQ(list.size(), 3u);
  EXPECT_EQ(list[0].kind, "depth");
  EXPECT_EQ(list[1].kind, "inversion");
  EXPECT_EQ(list[2].kind, "latent");
  EXPECT_EQ(list[2].bytes, 3100u) << "a latent is its array and its metadata";
  EXPECT_NEAR(list[1].age_days, 5, 0.01);
  const std::string out = c.dvs("list");
  EXPECT_NE(out.find("00000000000000b2"), std::string::npos) << out;
  EXPECT_EQ(out.find("00000000000000d4"), std::string::npos) << "a store under way is not an entry\n" << out;
  EXPECT_NE(out.find("3 entries, 6.0 KiB"), std::string::npos) << out;
}

TEST(CliCache, CleanByAgeThenBySizeNeverAWriterInProgress) {
  HandMadeCache c;
  std::string out = c.dvs("clean --older-than 7 --dry-run");
  EXPECT_NE(out.find("would remove 1 entries"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(c.folder / "latent-00000000000000c3.npy")) << "--dry-run removes nothing";

  out = c.dvs("clean --older-than 7");
  EXPECT_FALSE(fs::exists(c.folder / "latent-00000000000000c3.npy"));
  EXPECT_FALSE(fs::exists(c.folder / "latent-00000000000000c3.json"));
  EXPECT_TRUE(fs::exists(c.folder / "eps_inv-00000000000000b2.npy"));
  EXPECT_TRUE(fs::exists(c.folder / "depth-00000000000000a1.npy"));
  EXPECT_TRUE(fs::exists(c.folder / "latent-00000000000000d4.json")) << "a store under way is left alone";
  EXPECT_TRUE(fs::exists(c.folder / ("eps_inv-00000000000000e5.npy.tmp-" + std::to_string(::getpid()) + "-0")))
      << "a live process's file being written is never removed";
  EXPECT_FALSE(fs::exists(c.folder / "depth-00000000000000f6.npy.tmp-4194305-0")) << "a dead writer's leftover is";
  EXPECT_TRUE(fs::exists(c.folder / "notes.txt"));

  // 3000 bytes left; at most 1500: the least recently used (the 5-day inversion) goes, the depth stays.
  out = c.dvs("clean --max-size 1500");
  EXPECT_FALSE(fs::exists(c.folder / "eps_inv-00000000000000b2.npy")) << out;
  EXPECT_TRUE(fs::exists(c.folder / "depth-00000000000000a1.npy")) << out;
  out = c.dvs("clean --all");
  EXPECT_TRUE(list_cache(c.folder).empty()) << out;
}

TEST(CliCache, CleanSaysWhatToRemove) {
  HandMadeCache c;
  for (const std::string args : {"clean", "clean --max-size lots", "clean --older-than -1", "list --all", "purge"}) {
    const auto r = test::run_command(test::program("dvs") + " cache " + args + " --cache-dir " + c.folder.string());
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
  }
  EXPECT_EQ(list_cache(c.folder).size(), 3u);
}

TEST(CliCache, ByteSizes) {
  EXPECT_EQ(parse_byte_size("1048576"), 1048576u);
  EXPECT_EQ(parse_byte_size("500M"), 500ull << 20);
  EXPECT_EQ(parse_byte_size("2G"), 2ull << 30);
  EXPECT_EQ(parse_byte_size("1.5GiB"), 3ull << 29);
  EXPECT_EQ(parse_byte_size("10kB"), 10240u);
  EXPECT_FALSE(parse_byte_size("lots"));
  EXPECT_FALSE(parse_byte_size("-1G"));
  EXPECT_FALSE(parse_byte_size(""));
}

}  // namespace
}  // namespace dvs
