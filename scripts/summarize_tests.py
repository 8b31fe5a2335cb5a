#!/usr/bin/python3
"""Summarise the JUnit XML files a catkin test run wrote.

Prints each failing test case with its message, then one line
"N passed, N failed[, N skipped]". Exit status 1 when any test failed, when a
result file is missing or unreadable, or when no test ran at all.
"""
import glob
import os
import sys
import xml.etree.ElementTree as ET


def main(results_dir):
    files = sorted(glob.glob(os.path.join(results_dir, "**", "*.xml"), recursive=True))
    passed = failed = skipped = 0
    broken = []
    for path in files:
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError as err:
            broken.append("%s: unreadable result file (%s)" % (path, err))
            failed += 1
            continue
        cases = root.iter("testcase")
        any_case = False
        for case in cases:
            any_case = True
            name = "%s.%s" % (case.get("classname", "?"), case.get("name", "?"))
            problems = case.findall("failure") + case.findall("error")
            if problems:
                failed += 1
                text = (problems[0].get("message") or problems[0].text or "").strip()
                print("FAILED %s (%s)\n  %s" % (name, os.path.basename(path), text[:2000]))
            elif case.find("skipped") is not None or case.get("status") == "notrun":
                skipped += 1
                print("SKIPPED %s" % name)
            else:
                passed += 1
        if not any_case:
            broken.append("%s: no test case in result file" % path)
            failed += 1
    for b in broken:
        print("FAILED " + b)
    line = "%d passed, %d failed" % (passed, failed)
    if skipped:
        line += ", %d skipped" % skipped
    print(line)
    return 1 if failed or passed == 0 else 0


if __name__ == "__main__":
    if sys.argv[1:2] in (["-h"], ["--help"]):
        print("usage: summarize_tests.py [RESULTS_DIR]\n" + __doc__)
        sys.exit(0)
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "."))
