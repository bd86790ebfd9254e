#!/usr/bin/env python3
"""Counts test cases in the JUnit XML files that catkin's run_tests wrote.

- gtest-*.xml: one file per gtest suite; every test case counts.
- script-*.xml: a test script run by scripts/test.sh (test/install/test_install.sh); every case counts.
- MISSING-*.xml: written by catkin when a test produced no result file (a crash): one failure.
- rosunit-<test-name>.xml: the gtest cases of a rostest's test node; every case counts.
- rostest-*.xml: one summary case per <test> of a launch file ("test<test-name>"). It is not
  counted again when it passed; when it failed (node crash, time limit, no results) and the test
  node's own file shows no failing case, it counts as one failure, so nothing fails silently.
Prints failing cases, then "N passed, N failed"; exits 1 if any case failed or none ran.
"""
import os
import sys
import xml.etree.ElementTree as ET


def cases_of(path):
    """Returns [(name, failed)] or None if the file cannot be parsed."""
    try:
        tree = ET.parse(path)
    except ET.ParseError:
        return None
    out = []
    for c in tree.iter("testcase"):
        if c.find("skipped") is not None or c.get("status") == "notrun":
            continue
        failed = c.find("failure") is not None or c.find("error") is not None
        out.append((f"{c.get('classname', '')}.{c.get('name', '')}", failed))
    return out


def main(results_dir):
    passed, failed, failures = 0, 0, []
    files = {}
    for root, _, names in os.walk(results_dir):
        for n in names:
            if n.endswith(".xml"):
                files[n] = os.path.join(root, n)

    def count(name, cases):
        nonlocal passed, failed
        if cases is None:
            failed += 1
            failures.append(f"{name}: unreadable result file")
            return
        if not cases:
            failed += 1
            failures.append(f"{name}: no test cases recorded")
            return
        for case, bad in cases:
            if bad:
                failed += 1
                failures.append(f"{name}: {case}")
            else:
                passed += 1

    for n in sorted(files):
        if n.startswith(("gtest-", "rosunit-", "script-")):
            count(n, cases_of(files[n]))
        elif n.startswith("MISSING-"):
            # catkin writes these when a test binary produced no results (crash, abort).
            failed += 1
            failures.append(f"{n}: the test produced no results (crashed?)")
    for n in sorted(files):
        if not n.startswith("rostest-"):
            continue
        summary = cases_of(files[n])
        if summary is None:
            count(n, None)
            continue
        for case, bad in summary:
            test_name = case.split(".")[-1]
            test_name = test_name[4:] if test_name.startswith("test") else test_name
            node_file = f"rosunit-{test_name}.xml"
            node_cases = cases_of(files[node_file]) if node_file in files else None
            if bad and not (node_cases and any(b for _, b in node_cases)):
                failed += 1
                failures.append(f"{n}: {case} (rostest failed: crash, time limit or missing results)")
            elif not bad and node_file not in files:
                passed += 1
    for f in failures:
        print(f"FAILED: {f}")
    print(f"{passed} passed, {failed} failed")
    return 1 if failed or passed == 0 else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "."))
