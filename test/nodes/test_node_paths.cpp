// The nodes' ROS-free parameter helpers (src/nodes/node_paths.h): home expansion, the words of
// ~database_build_command and the package tool found beside the running executable.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "../../src/nodes/node_paths.h"

namespace textile_handling {
namespace {

using Words = std::vector<std::string>;

TEST(NodePaths, HomeExpandsOnlyAtTheStart) {
  ::setenv("HOME", "/home/cell", 1);
  EXPECT_EQ(expandHome("~/.ros/drapes.sqlite"), "/home/cell/.ros/drapes.sqlite");
  EXPECT_EQ(expandHome("/data/~/x"), "/data/~/x");
  EXPECT_EQ(expandHome("postgresql://cell@db/drapes"), "postgresql://cell@db/drapes");
}

TEST(NodePaths, ACommandStringSplitsAtWhitespace) {
  EXPECT_EQ(splitCommandWords("mpirun  -np 4\t--hostfile /etc/hosts drape_db build --mpi"),
            (Words{"mpirun", "-np", "4", "--hostfile", "/etc/hosts", "drape_db", "build", "--mpi"}));
  EXPECT_TRUE(splitCommandWords("").empty());
  EXPECT_TRUE(splitCommandWords("  \t ").empty());
}

TEST(NodePaths, TheToolWordBecomesItsPathOrTheParameterIsRefused) {
  const Words words = {"mpirun", "-np", "2", "drape_db", "build", "--mpi"};
  EXPECT_EQ(withToolPath(words, "drape_db", "/opt/th/lib/drape_db", "p"),
            (Words{"mpirun", "-np", "2", "/opt/th/lib/drape_db", "build", "--mpi"}));
  // Only whole words: a path that contains the name stays as given.
  EXPECT_EQ(withToolPath({"/usr/local/bin/drape_db", "build"}, "drape_db", "", "p"),
            (Words{"/usr/local/bin/drape_db", "build"}));
  try {
    withToolPath(words, "drape_db", "", "parameter ~database_build_command");
    ADD_FAILURE() << "a missing tool was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("~database_build_command"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("give its path"), std::string::npos) << e.what();
  }
}

TEST(NodePaths, APackageToolIsFoundBesideTheRunningExecutable) {
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe");
  EXPECT_EQ(packageToolPath(self.filename().string()), self.string());
  EXPECT_EQ(packageToolPath("no_such_tool_anywhere"), "");
}

}  // namespace
}  // namespace textile_handling
