// Runs one external build command (a `drape_db build --job FILE` command line, possibly under mpirun)
// for TextileRegistry: in a process group of its own, its standard output and error read line by line,
// stopped with SIGTERM (then SIGKILL) when the registry shuts down. ROS-free. docs/build_farm.md.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace textile_handling {
namespace registry {

struct ExternalCommandOutcome {
  bool started = false;        ///< the program could be run (false: *error says why, e.g. not found)
  bool exited = false;         ///< ended by exit(); exit_code is valid
  int exit_code = -1;
  int signal = 0;              ///< the signal that ended it (exited = false)
  bool stopped = false;        ///< should_stop asked for the end and the command was terminated
  std::vector<std::string> tail;  ///< its last output lines (at most 20), for error messages
  std::string error;           ///< why it could not be started
};

/// Runs `argv` (argv[0] a path, or a name looked up in PATH) with stdout and stderr joined into one pipe,
/// calling `on_line` for every output line (without the newline; lines over 64 KiB are cut) from the
/// calling thread. Polls `should_stop` (if set) every 100 ms: once it returns true, the process group gets
/// SIGTERM and, if it has not ended after `grace_s`, SIGKILL. Returns when the command has ended and its
/// output is drained (or, if a process of the group keeps the pipe open, 1 s after the command ended).
/// Never throws for a command that fails; throws std::invalid_argument for an empty argv.
ExternalCommandOutcome runExternalCommand(const std::vector<std::string>& argv,
                                          const std::function<void(const std::string& line)>& on_line,
                                          const std::function<bool()>& should_stop = {}, double grace_s = 10);

/// A readable description of how the command ended: "exit status 3", "killed by signal 9 (Killed)", ...
std::string describeOutcome(const ExternalCommandOutcome& outcome);

}  // namespace registry
}  // namespace textile_handling
