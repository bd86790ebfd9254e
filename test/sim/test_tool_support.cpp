// Output directories and files (modes under any umask, every write checked), bounded text input and
// the tools' thread limits.
#include <gtest/gtest.h>
#include <omp.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "textile_handling/sim/output_files.h"
#include "textile_handling/sim/text_input.h"
#include "textile_handling/sim/thread_limit.h"

namespace textile_handling {
namespace {

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

unsigned modeOf(const std::string& path) {
  struct stat st{};
  EXPECT_EQ(::stat(path.c_str(), &st), 0) << path;
  return st.st_mode & 07777;
}

// A fresh directory under the test temporary directory, removed at the end.
struct ScratchDir {
  std::string path;
  explicit ScratchDir(const std::string& name) : path(::testing::TempDir() + "/th_" + name + "_" + std::to_string(::getpid())) {
    std::filesystem::remove_all(path);
  }
  ~ScratchDir() { std::filesystem::remove_all(path); }
};

// Sets the umask for one scope.
struct UmaskGuard {
  mode_t old;
  explicit UmaskGuard(mode_t m) : old(::umask(m)) {}
  ~UmaskGuard() { ::umask(old); }
};

TEST(CreateDirectories, EveryNewComponentGetsTheModeWhateverTheUmask) {
  ScratchDir dir("mkdir");
  {
    UmaskGuard guard(0);
    createDirectories(dir.path + "/a/b/c");
  }
  EXPECT_EQ(modeOf(dir.path), 0755u);
  EXPECT_EQ(modeOf(dir.path + "/a"), 0755u);
  EXPECT_EQ(modeOf(dir.path + "/a/b"), 0755u);
  EXPECT_EQ(modeOf(dir.path + "/a/b/c"), 0755u);
  {
    UmaskGuard guard(077);
    createDirectories(dir.path + "/a/d//e/", 0750);
  }
  EXPECT_EQ(modeOf(dir.path + "/a/d"), 0750u);
  EXPECT_EQ(modeOf(dir.path + "/a/d/e"), 0750u);
  // Existing directories keep their mode; creating again is not an error.
  EXPECT_EQ(modeOf(dir.path + "/a"), 0755u);
  EXPECT_NO_THROW(createDirectories(dir.path + "/a/b/c"));
}

TEST(CreateDirectories, AFileInTheWayIsAnErrorNamingThePath) {
  ScratchDir dir("mkdir_file");
  createDirectories(dir.path);
  { std::ofstream(dir.path + "/file") << "x"; }
  try {
    createDirectories(dir.path + "/file/sub");
    ADD_FAILURE() << "accepted";
  } catch (const OutputError& e) {
    EXPECT_TRUE(contains(e.what(), dir.path + "/file")) << e.what();
  }
  EXPECT_THROW(createDirectories(""), OutputError);
  EXPECT_THROW(checkWritableDirectory(dir.path + "/file"), OutputError);
  EXPECT_THROW(checkWritableDirectory(dir.path + "/missing"), OutputError);
  EXPECT_NO_THROW(checkWritableDirectory(dir.path));
  // The probe leaves nothing behind.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path), std::filesystem::directory_iterator()), 1);
}

TEST(WriteFileAtomically, WritesTheFileOrThrowsAndLeavesNothing) {
  ScratchDir dir("atomic");
  createDirectories(dir.path);
  const std::string path = dir.path + "/out.txt";
  writeFileAtomically(path, [](std::ostream& f) { f << "hello\n"; });
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), "hello\n");
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  try {
    writeFileAtomically(dir.path + "/missing/out.txt", [](std::ostream& f) { f << "x"; });
    ADD_FAILURE() << "accepted";
  } catch (const OutputError& e) {
    EXPECT_TRUE(contains(e.what(), dir.path + "/missing/out.txt")) << e.what();
  }
}

TEST(WriteFileAtomically, AFullDiskIsAnError) {
  // The temporary file is a link to /dev/full: opening works, every write fails with ENOSPC.
  ScratchDir dir("full");
  createDirectories(dir.path);
  const std::string path = dir.path + "/out.txt";
  std::filesystem::create_symlink("/dev/full", path + ".tmp");
  try {
    writeFileAtomically(path, [](std::ostream& f) { f << std::string(1 << 16, 'x'); });
    ADD_FAILURE() << "a write to a full disk was reported as success";
  } catch (const OutputError& e) {
    EXPECT_TRUE(contains(e.what(), path)) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(BoundedTextFile, ReadsSmallRegularFilesOnly) {
  ScratchDir dir("text");
  createDirectories(dir.path);
  const std::string path = dir.path + "/a.yaml";
  { std::ofstream(path) << "key: value\n"; }
  std::string text, error;
  ASSERT_TRUE(readBoundedTextFile(path, 100, &text, &error)) << error;
  EXPECT_EQ(text, "key: value\n");
  EXPECT_FALSE(readBoundedTextFile(path, 5, &text, &error));
  EXPECT_TRUE(contains(error, "limit of 5")) << error;
  EXPECT_FALSE(readBoundedTextFile(dir.path, 100, &text, &error));
  EXPECT_TRUE(contains(error, "not a regular file")) << error;
  EXPECT_FALSE(readBoundedTextFile("/dev/zero", 100, &text, &error));
  EXPECT_FALSE(readBoundedTextFile(dir.path + "/missing", 100, &text, &error));
  EXPECT_TRUE(contains(error, dir.path + "/missing")) << error;
}

TEST(ThreadLimit, ParsesStrictlyAndCaps) {
  int n = 0;
  std::string error;
  EXPECT_TRUE(parseThreadCount("2", &n, &error));
  EXPECT_EQ(n, 2);
  for (const std::string bad : {"0", "-1", "100000", "abc", "4x", "", "1e3", "99999999999999999999"}) {
    EXPECT_FALSE(parseThreadCount(bad, &n, &error)) << bad;
    EXPECT_TRUE(contains(error, "--threads")) << error;
  }
  const int before = omp_get_max_threads();
  std::string note;
  const int used = applyThreadLimit(kMaxRequestableThreads, &note);
  EXPECT_EQ(used, maxUsefulThreads());
  EXPECT_LE(omp_get_max_threads(), maxUsefulThreads());
  EXPECT_TRUE(contains(note, "using")) << note;
  EXPECT_EQ(applyThreadLimit(1, &note), 1);
  EXPECT_TRUE(note.empty());
  omp_set_num_threads(before);
}

}  // namespace
}  // namespace textile_handling
