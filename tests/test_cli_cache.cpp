// `dvs cache list` and `dvs cache clean` on a cache folder made by hand: entries of known sizes and ages, a
// latent whose metadata is written but whose array is not yet (a store under way), and temporary files of a
// live writer (this test's own process) and of a dead one. Clean removes by age, then the least recently used
// down to the size, and never a file a live process is writing. The folder means the same to --cache-dir and
// DVS_CACHE_DIR (issue 34), entries left by the earlier layout are named with the commands that move them, and
// the list shows each entry's data file.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <optional>

#include "dvs/cache.hpp"
#include "support/files.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

struct HandMadeCache {
  test::TempDir dir;
  fs::path root = dir / "c";              // the cache folder (--cache-dir, DVS_CACHE_DIR)
  fs::path folder = root / "inversions";  // its entries
  // days: how long ago the entry was last used.
  void put(const std::string& name, size_t bytes, double days) {
    test::write_text(folder / name, std::string(bytes, 'x'));
    fs::last_write_time(folder / name, fs::file_time_type::clock::now() - std::chrono::seconds(int64_t(days * 86400)));
  }
  HandMadeCache() {
    put("depth-00000000000000a1.npy", 1000, 1);
    put("depth-00000000000000a1.npy.sum", 40, 1);  // the commit marker (pipeline/cache_entry.hpp)
    put("eps_inv-00000000000000b2.npy", 2000, 5);
    put("latent-00000000000000c3.npy", 3000, 10);
    put("latent-00000000000000c3.json", 100, 10);
    put("latent-00000000000000d4.json", 100, 20);  // metadata only: the latent's store is under way
    put("eps_inv-00000000000000e5.npy.tmp-" + std::to_string(::getpid()) + "-0", 500, 30);  // a live writer's
    put("depth-00000000000000f6.npy.tmp-4194305-0", 500, 30);  // pid > PID_MAX_LIMIT: never alive
    put("notes.txt", 10, 40);                                   // not the cache's
  }
  std::string dvs(const std::string& args) const {
    const auto r = test::run_command(test::program("dvs") + " cache " + args + " --cache-dir " + root.string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return r.output;
  }
};

TEST(CliCache, ListsCompleteEntriesMostRecentlyUsedFirst) {
  HandMadeCache c;
  const auto list = list_cache(c.root);
  ASSERT_EQ(list.size(), 3u);
  EXPECT_EQ(list[0].kind, "depth");
  EXPECT_EQ(list[1].kind, "inversion");
  EXPECT_EQ(list[2].kind, "latent");
  EXPECT_EQ(list[2].bytes, 3100u) << "a latent is its array and its metadata";
  EXPECT_NEAR(list[1].age_days, 5, 0.01);
  const std::string out = c.dvs("list");
  EXPECT_NE(out.find("00000000000000b2"), std::string::npos) << out;
  EXPECT_EQ(out.find("00000000000000d4"), std::string::npos) << "a store under way is not an entry\n" << out;
  EXPECT_NE(out.find("3 entries, 6.0 KiB in " + c.folder.string()), std::string::npos) << out;
  // Each entry's data file, not its commit marker.
  EXPECT_EQ(list[0].data_file, c.folder / "depth-00000000000000a1.npy");
  EXPECT_NE(out.find(" " + (c.folder / "depth-00000000000000a1.npy").string() + "\n"), std::string::npos) << out;
  EXPECT_EQ(out.find(".sum"), std::string::npos) << out;
}

// One meaning for the folder: DVS_CACHE_DIR=DIR and --cache-dir DIR list the same entries of the same folder,
// DIR/inversions (before, --cache-dir DIR listed DIR itself: 0 entries, and a run recomputed what was cached).
TEST(CliCache, TheVariableAndTheOptionNameTheSameFolder) {
  HandMadeCache c;
  const auto by_option = test::run_command(test::program("dvs") + " cache list --cache-dir " + c.root.string());
  const auto by_variable = test::run_command("DVS_CACHE_DIR=" + c.root.string() + " " + test::program("dvs") + " cache list");
  ASSERT_EQ(by_option.exit_code, 0) << by_option.output;
  ASSERT_EQ(by_variable.exit_code, 0) << by_variable.output;
  EXPECT_EQ(by_option.output, by_variable.output);
  EXPECT_NE(by_option.output.find("3 entries"), std::string::npos) << by_option.output;
  EXPECT_EQ(cache_folder(c.root), c.folder);
  EXPECT_EQ(list_cache(c.root).size(), 3u);
  EXPECT_EQ(old_cache_layout(c.root), std::nullopt);
}

// The earlier layout (entries directly in the --cache-dir folder) is named, with the commands that move the entries
// into place; run as printed, the entries are the cache's again. A folder named inversions that holds entries is
// the entries folder of the one above: that is the folder to give.
TEST(CliCache, AnEarlierLayoutIsNamedWithTheCommandsThatMoveIt) {
  HandMadeCache c;
  const fs::path old = c.dir / "old";
  fs::rename(c.folder, old);  // the entries directly in the folder given
  const auto before = test::run_command(test::program("dvs") + " cache list --cache-dir " + old.string());
  ASSERT_EQ(before.exit_code, 0) << before.output;
  EXPECT_NE(before.output.find("0 entries"), std::string::npos) << before.output;
  const std::string marker = "Move them there to keep them: ";
  const size_t at = before.output.find(marker);
  ASSERT_NE(at, std::string::npos) << before.output;
  EXPECT_NE(before.output.find("note: " + old.string() + ": the cache folder holds 6 entry files directly in it"),
            std::string::npos) << before.output;
  const std::string move = before.output.substr(at + marker.size(), before.output.find('\n', at) - at - marker.size());
  const auto moved = test::run_command(move);
  ASSERT_EQ(moved.exit_code, 0) << move << "\n" << moved.output;
  const auto after = test::run_command(test::program("dvs") + " cache list --cache-dir " + old.string());
  EXPECT_NE(after.output.find("3 entries"), std::string::npos) << after.output;
  EXPECT_EQ(after.output.find("note:"), std::string::npos) << after.output;
  EXPECT_EQ(list_cache(old).size(), 3u);

  // The entries folder itself given as the cache folder (what the default's entries folder was to --cache-dir).
  const auto inner = test::run_command(test::program("dvs") + " cache list --cache-dir " + cache_folder(old).string());
  EXPECT_NE(inner.output.find("give that folder instead (--cache-dir " + old.string() + ", or DVS_CACHE_DIR)"),
            std::string::npos) << inner.output;
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
  EXPECT_TRUE(list_cache(c.root).empty()) << out;
}

TEST(CliCache, CleanSaysWhatToRemove) {
  HandMadeCache c;
  for (const std::string args : {"clean", "clean --max-size lots", "clean --older-than -1", "list --all", "purge"}) {
    const auto r = test::run_command(test::program("dvs") + " cache " + args + " --cache-dir " + c.root.string());
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
  }
  EXPECT_EQ(list_cache(c.root).size(), 3u);
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
