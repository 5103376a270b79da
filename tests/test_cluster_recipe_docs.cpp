// The Slurm example the documents show is the script the cluster test runs (tests/cluster/test_slurm_array.cpp
// submits docs/examples/slurm_batch.sh to a real Slurm): every fenced code block of README.md and docs/*.md that
// holds an #SBATCH line must be that file, byte for byte, so a recipe edited in one place fails here.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "support/files.hpp"
#include "support/source_dir.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

// The bodies of the ``` fenced blocks of a Markdown text (the fence lines themselves left out).
std::vector<std::string> fenced_blocks(const std::string& markdown) {
  std::vector<std::string> blocks;
  std::string body;
  bool inside = false;
  size_t at = 0;
  while (at < markdown.size()) {
    const size_t end = markdown.find('\n', at);
    const std::string line = markdown.substr(at, end == std::string::npos ? std::string::npos : end - at);
    at = end == std::string::npos ? markdown.size() : end + 1;
    if (line.rfind("```", 0) == 0) {
      if (inside) blocks.push_back(body);
      inside = !inside;
      body.clear();
    } else if (inside) {
      body += line + "\n";
    }
  }
  return blocks;
}

TEST(ClusterRecipeDocs, FencedBlocksAreFound) {
  const auto blocks = fenced_blocks("text\n```sh\na\nb\n```\nmore\n```\nc\n```\n```\nunclosed\n");
  ASSERT_EQ(blocks.size(), 2u);
  EXPECT_EQ(blocks[0], "a\nb\n");
  EXPECT_EQ(blocks[1], "c\n");
}

TEST(ClusterRecipeDocs, EverySlurmExampleIsTheTestedScript) {
  const fs::path root = test::source_dir(), recipe = root / "docs" / "examples" / "slurm_batch.sh";
  const std::string script = test::read_text(recipe);
  ASSERT_NE(script.find("#SBATCH --array="), std::string::npos) << recipe << " is not a Slurm array job";
  std::vector<fs::path> documents{root / "README.md"};
  for (const auto& e : fs::directory_iterator(root / "docs"))
    if (e.path().extension() == ".md") documents.push_back(e.path());
  int shown = 0;
  for (const fs::path& doc : documents)
    for (const std::string& block : fenced_blocks(test::read_text(doc)))
      if (block.find("#SBATCH") != std::string::npos) {
        ++shown;
        EXPECT_EQ(block, script) << doc << " shows a Slurm example that is not " << recipe
                                 << " (the tested script): show the file as it is";
      }
  EXPECT_GE(shown, 1) << "no document shows the Slurm recipe " << recipe;
}

}  // namespace
}  // namespace dvs
