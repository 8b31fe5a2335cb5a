#!/usr/bin/python3
"""Rebuild the README's node sections from doc/nodes/<node>.md.

Each node's page is the one place its topics, services and parameters are
written; this copies them, headings shifted under the README's "## Nodes",
between the markers <!-- NODES --> and <!-- /NODES -->.
"""
import os
import re
import sys

ORDER = ["camera_capture", "target_centroider", "hex_matcher", "dense_matcher", "bundle_adjuster",
         "radio_phase_solver", "deformation_estimator", "make_survey_bag"]


def shifted(text, top_level=3):
    levels = [len(m.group(1)) for m in re.finditer(r"^(#+) ", text, re.M)]
    if not levels:
        return text
    shift = top_level - min(levels)
    out, fence = [], False
    for line in text.splitlines():
        if line.startswith("```"):
            fence = not fence
        m = re.match(r"^(#+) (.*)$", line)
        if m and not fence:
            line = "#" * min(6, len(m.group(1)) + shift) + " " + m.group(2)
        out.append(line)
    return "\n".join(out).strip() + "\n"


def main(root):
    docs = os.path.join(root, "doc", "nodes")
    names = [n for n in ORDER if os.path.exists(os.path.join(docs, n + ".md"))]
    names += sorted(f[:-3] for f in os.listdir(docs) if f.endswith(".md") and f[:-3] not in names)
    body = "\n".join(shifted(open(os.path.join(docs, n + ".md")).read()) for n in names)
    readme_path = os.path.join(root, "README.md")
    readme = open(readme_path).read()
    start, end = "<!-- NODES -->", "<!-- /NODES -->"
    if end not in readme:
        readme = readme.replace(start, start + "\n" + end)
    head, rest = readme.split(start, 1)
    _, tail = rest.split(end, 1)
    open(readme_path, "w").write(head + start + "\n\n" + body + "\n" + end + tail)
    print("README.md: %d node sections" % len(names))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
