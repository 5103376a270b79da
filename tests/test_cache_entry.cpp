// Cache entries (pipeline/cache_entry.hpp) are verified before use: an entry without its commit marker (a write
// cut short), shorter or longer than its marker says (torn), with a changed byte, or with a damaged marker is
// reported and never returned; one published again while others read it is never seen half-written.
#include <gtest/gtest.h>

#include <atomic>
#include <fstream>
#include <thread>

#include "dvs/error.hpp"
#include "io/npy.hpp"
#include "pipeline/cache_entry.hpp"
#include "support/files.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

HostTensor ramp(float start, int n = 1000) {
  std::vector<float> v(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) v[size_t(i)] = start + float(i);
  return HostTensor::from_f32({n}, v);
}

TEST(CacheEntry, AWholeEntryIsReadBack) {
  test::TempDir d;
  const fs::path f = d / "eps_inv-0000000000000001.npy";
  EXPECT_FALSE(read_cache_entry(f).tensor);
  EXPECT_TRUE(read_cache_entry(f).problem.empty()) << "no entry is no problem";
  write_cache_entry(f, ramp(1));
  const CacheEntryRead r = read_cache_entry(f);
  ASSERT_TRUE(r.tensor) << r.problem;
  EXPECT_EQ(r.tensor->data, ramp(1).data);
  EXPECT_EQ(read_npy(f).data, ramp(1).data) << "the entry itself is a plain .npy file";
  EXPECT_TRUE(cache_entry_exists(f));
  for (const auto& name : test::files_in(d.path))
    EXPECT_TRUE(name == f.filename().string() || name == commit_marker(f).filename().string() || name == ".dvs-cache-lock") << name;
}

TEST(CacheEntry, DamagedEntriesAreReportedNeverReturned) {
  test::TempDir d;
  const fs::path f = d / "latent-0000000000000002.npy";
  struct Damage {
    const char* what;
    std::function<void()> apply;
    const char* said;
  };
  const std::vector<Damage> damages = {
      {"no marker (a write cut short)", [&] { fs::remove(commit_marker(f)); }, "no commit marker"},
      {"truncated data", [&] { fs::resize_file(f, fs::file_size(f) - 100); }, "(torn)"},
      {"data longer than its marker says", [&] { std::ofstream(f, std::ios::app) << "xx"; }, "(torn)"},
      {"a changed byte", [&] {
         std::fstream s(f, std::ios::in | std::ios::out | std::ios::binary);
         s.seekp(200);
         s.put('\x7f');
       }, "do not match the checksum"},
      {"a damaged marker", [&] { test::write_text(commit_marker(f), "dvs-cache-entry 1 12"); }, "commit marker latent-0000000000000002.npy.sum is damaged"},
      {"data replaced by another whole .npy", [&] { write_npy(f, ramp(5)); }, "do not match the checksum"},
  };
  for (const auto& dmg : damages) {
    write_cache_entry(f, ramp(2));
    dmg.apply();
    const CacheEntryRead r = read_cache_entry(f);
    EXPECT_FALSE(r.tensor) << dmg.what;
    EXPECT_NE(r.problem.find(dmg.said), std::string::npos) << dmg.what << ": " << r.problem;
    remove_cache_entry(f);
    EXPECT_FALSE(fs::exists(f) || fs::exists(commit_marker(f))) << dmg.what;
  }
}

TEST(CacheEntry, AnUnwritableFolderIsAnErrorNamingTheEntry) {
  test::TempDir d;
  const fs::path f = d / "missing" / "depth-0000000000000003.npy";
  try {
    write_cache_entry(f, ramp(3));
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(f.string()), std::string::npos) << e.what();
  }
}

// Two writers publish the same entry over and over (each with its own, whole contents) while a reader reads it:
// the reader only ever gets one writer's contents or the other's, never a problem.
TEST(CacheEntry, ReadersNeverSeeAHalfPublishedEntry) {
  test::TempDir d;
  const fs::path f = d / "eps_inv-0000000000000004.npy";
  const HostTensor a = ramp(10, 20000), b = ramp(-7, 20000);
  write_cache_entry(f, a);
  std::atomic<bool> stop{false};
  std::atomic<int> reads{0}, problems{0};
  std::string first_problem;
  std::thread reader([&] {
    while (!stop) {
      const CacheEntryRead r = read_cache_entry(f);
      if (!r.tensor || (r.tensor->data != a.data && r.tensor->data != b.data)) {
        if (problems++ == 0) first_problem = r.tensor ? "mixed contents" : r.problem;
      }
      ++reads;
    }
  });
  std::thread wa([&] { for (int i = 0; i < 40; ++i) write_cache_entry(f, a); });
  std::thread wb([&] { for (int i = 0; i < 40; ++i) write_cache_entry(f, b); });
  wa.join();
  wb.join();
  stop = true;
  reader.join();
  EXPECT_GT(reads.load(), 0);
  EXPECT_EQ(problems.load(), 0) << first_problem;
  for (const auto& name : test::files_in(d.path)) EXPECT_EQ(name.find(".tmp-"), std::string::npos) << name;
}

}  // namespace
}  // namespace dvs
