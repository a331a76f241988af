#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The Cycles patch carries neuralyarn's kernel headers (cycles_patch/0000-neuralyarn-kernel-headers.patch
adds them as intern/cycles/kernel/closure/neuralyarn/*.h), so that the patched Cycles needs nothing from
outside its own tree. They must stay byte-identical to cpp_core/include/neuralyarn/kernel/:

    python3 scripts/cycles_kernel_headers.py --check    # exit 1 and say which file differs (CTest runs it)
    python3 scripts/cycles_kernel_headers.py            # rewrite the patch's header files from cpp_core

The rewrite keeps the patch's other part (the kernel CMakeLists' SRC_KERNEL_NEURALYARN_HEADERS list and its
install) as it is; a header added or removed in cpp_core must be listed there by hand, which --check says.
Standard library only.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import re
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))
PATCH = os.path.join(ROOT, "cycles_patch", "0000-neuralyarn-kernel-headers.patch")
SOURCE = os.path.join(ROOT, "cpp_core", "include", "neuralyarn", "kernel")
TARGET = "intern/cycles/kernel/closure/neuralyarn/"


def blocks(text: str) -> list[str]:
    """The patch split into its files' blocks ("diff --git ..." to the next)."""
    parts = re.split(r"(?m)^(?=diff --git )", text)
    return [p for p in parts if p]


def block_path(block: str) -> str:
    return re.match(r"diff --git a/(\S+) b/", block).group(1)


def new_file_content(block: str) -> str:
    """The content a new-file block adds (its '+' lines), as the file's text."""
    lines = block.split("\n")
    body = lines[lines.index(next(ln for ln in lines if ln.startswith("@@ "))) + 1:]
    out, no_newline = [], False
    for ln in body:
        if ln.startswith("+"):
            out.append(ln[1:])
        elif ln.startswith("\\ No newline at end of file"):
            no_newline = True
    return "\n".join(out) + ("" if no_newline else "\n")


def new_file_block(path: str, content: str) -> str:
    """A new-file block as `git diff` writes it."""
    data = content.encode("utf-8")
    blob = hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()[:7]
    lines = content.split("\n")
    tail = ""
    if lines[-1] == "":
        lines.pop()
    else:
        tail = "\\ No newline at end of file\n"
    return (f"diff --git a/{path} b/{path}\nnew file mode 100644\nindex 0000000..{blob}\n--- /dev/null\n"
            f"+++ b/{path}\n@@ -0,0 +1,{len(lines)} @@\n" + "".join(f"+{ln}\n" for ln in lines) + tail)


def headers() -> dict[str, str]:
    return {name: open(os.path.join(SOURCE, name), encoding="utf-8").read()
            for name in sorted(os.listdir(SOURCE)) if name.endswith(".h")}


def listed(text: str) -> list[str]:
    """The names in the patch's SRC_KERNEL_NEURALYARN_HEADERS list."""
    m = re.search(r"(?ms)^\+set\(SRC_KERNEL_NEURALYARN_HEADERS\n(.*?)^\+\)", text)
    return sorted(re.findall(r"closure/neuralyarn/(\S+\.h)", m.group(1))) if m else []


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="only compare; exit 1 on any difference")
    args = ap.parse_args(argv)
    text = open(PATCH, encoding="utf-8").read()
    source = headers()
    problems = []
    if listed(text) != sorted(source):
        problems.append(f"the patch's SRC_KERNEL_NEURALYARN_HEADERS lists {listed(text)}, cpp_core has "
                        f"{sorted(source)}: edit the list in {os.path.relpath(PATCH, ROOT)}")
    others = [b for b in blocks(text) if not block_path(b).startswith(TARGET)]
    carried = {block_path(b)[len(TARGET):]: new_file_content(b) for b in blocks(text) if block_path(b).startswith(TARGET)}
    for name in sorted(set(source) | set(carried)):
        if carried.get(name) != source.get(name):
            what = "is missing from the patch" if name not in carried else \
                "is not in cpp_core" if name not in source else "differs from cpp_core's"
            problems.append(f"{TARGET}{name} {what}")
    if args.check:
        for p in problems:
            print(f"cycles_kernel_headers: {p}", file=sys.stderr)
        if problems:
            print("cycles_kernel_headers: run `python3 scripts/cycles_kernel_headers.py` to carry cpp_core's headers",
                  file=sys.stderr)
            return 1
        print(f"cycles_kernel_headers: the patch carries cpp_core's {len(source)} kernel headers byte for byte")
        return 0
    new = "".join(others) + "".join(new_file_block(TARGET + name, content) for name, content in source.items())
    if new != text:
        tmp = PATCH + ".tmp"
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(new)
        os.replace(tmp, PATCH)
        print(f"rewrote {os.path.relpath(PATCH, ROOT)}")
    for p in problems:
        if p.startswith("the patch's"):
            print(f"cycles_kernel_headers: {p}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
