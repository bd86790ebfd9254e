#!/usr/bin/python3
"""Checks launch files the way roslaunch would load them, in one process (the roslaunch command line
would take a few seconds per query): each file parses with the given arguments (rosparam files named in
it are loaded, so they must exist), every launch file it includes lies under SHARE_DIR, and every node's
command line starts with an existing executable under one of the ALLOWED roots and names only existing
bag and YAML files under them. Prints each node's command line; exits 1 naming every problem.

Usage: check_launch_files.py SHARE_DIR ALLOWED_ROOTS(colon-separated) LAUNCH_FILE[,ARG:=VALUE...] ...
"""
import os
import sys

import roslaunch.config
import roslaunch.core
import roslaunch.node_args
import roslaunch.xmlloader


def under(path, roots):
    path = os.path.realpath(path)
    return any(path == r or path.startswith(r.rstrip("/") + "/") for r in roots)


def check(launch_file, launch_args, share_dir, roots):
    """Returns a list of problems of one launch file loaded with launch_args (["name:=value", ...])."""
    sys.argv = ["roslaunch"] + launch_args  # the XML loader reads arguments from sys.argv
    loader = roslaunch.xmlloader.XmlLoader(resolve_anon=False)
    try:
        config = roslaunch.config.load_config_default([launch_file], None, loader=loader, verbose=False,
                                                      assign_machines=False)
    except Exception as e:  # roslaunch raises several types for unparsable or unresolvable files
        return [f"{launch_file}: does not load: {e}"]
    problems = []
    core_file = os.path.realpath(roslaunch.config.get_roscore_filename())  # roslaunch loads it into every config
    for f in config.roslaunch_files:
        if os.path.realpath(f) != core_file and not under(f, [share_dir]):
            problems.append(f"{launch_file}: includes {f}, outside {share_dir}")
    for node in config.nodes + config.tests:
        try:
            cmd = roslaunch.node_args.create_local_process_args(node, roslaunch.core.local_machine())
        except Exception as e:
            problems.append(f"{launch_file}: node {node.name} ({node.package}/{node.type}): {e}")
            continue
        print(f"{os.path.basename(launch_file)}: {node.name}: {' '.join(cmd)}")
        exe = cmd[0]
        if not (os.path.isfile(exe) and os.access(exe, os.X_OK)):
            problems.append(f"{launch_file}: node {node.name}: {exe} is not an executable file")
        elif not under(exe, roots):
            problems.append(f"{launch_file}: node {node.name}: {exe} is outside {':'.join(roots)}")
        for word in cmd[1:]:
            if word.endswith((".bag", ".yaml")) and not (os.path.isfile(word) and under(word, roots)):
                problems.append(f"{launch_file}: node {node.name}: {word} missing or outside the allowed roots")
    return problems


def main(argv):
    if len(argv) < 4:
        print(__doc__)
        return 2
    share_dir = os.path.realpath(argv[1])
    roots = [os.path.realpath(r) for r in argv[2].split(":") if r]
    problems = []
    for spec in argv[3:]:
        launch_file, *launch_args = spec.split(",")
        problems += check(launch_file, launch_args, share_dir, roots)
    for p in problems:
        print(f"PROBLEM: {p}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
