#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Writes CHANGELOG.md in Debian's changelog form, gzipped: the changelog.gz of the Debian package
(cmake/package.cmake). Each version released as a Debian package (0.2.0 on: "## [X.Y.Z] -
YYYY-MM-DD") becomes one entry whose items are the release's bullets, each led by its section
("Added: ..."). Earlier releases were never packaged; the package holds CHANGELOG.md beside.

    debian_changelog.py CHANGELOG.md "Name <address>" OUT.gz
"""
import datetime
import gzip
import re
import sys
import textwrap

FIRST_PACKAGED = (0, 2, 0)


def releases(text):
    """[(version, date, [item, ...])], newest first, from Keep a Changelog markdown."""
    out = []
    section = None
    for line in text.splitlines():
        heading = re.match(r"## \[([^\]]+)\](?: - (\d{4}-\d{2}-\d{2}))?\s*$", line)
        if heading:
            version, date = heading.groups()
            if version == "Unreleased":
                section = None
                out.append(None)
                continue
            if not re.fullmatch(r"\d+\.\d+\.\d+", version) or not date:
                sys.exit(f"debian_changelog.py: bad release heading: {line}")
            out.append((version, datetime.date.fromisoformat(date), []))
            section = None
        elif line.startswith("### "):
            section = line[4:].strip()
        elif out and out[-1] is not None:
            items = out[-1][2]
            if line.startswith("- "):
                items.append(f"{section}: {line[2:].strip()}" if section else line[2:].strip())
            elif line.startswith("  ") and items:
                items[-1] += " " + line.strip()
            elif line.strip() and not items:
                items.append(line.strip())  # a release's introduction
    return [r for r in out if r is not None]


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    source, maintainer, output = sys.argv[1:]
    entries = []
    for version, date, items in releases(open(source, encoding="utf-8").read()):
        if tuple(int(part) for part in version.split(".")) < FIRST_PACKAGED:
            continue
        if not items:
            sys.exit(f"debian_changelog.py: {source}: release {version} lists nothing")
        lines = [f"btfkit ({version}) unstable; urgency=medium", ""]
        for item in items:
            item = item.replace("`", "")
            lines += textwrap.wrap(item, width=78, initial_indent="  * ",
                                   subsequent_indent="    ", break_on_hyphens=False)
        stamp = datetime.datetime.combine(date, datetime.time(), datetime.timezone.utc)
        lines += ["", f" -- {maintainer}  {stamp.strftime('%a, %d %b %Y %H:%M:%S +0000')}"]
        entries.append("\n".join(lines) + "\n")
    if not entries:
        sys.exit(f"debian_changelog.py: {source}: no release")
    data = "\n".join(entries).encode("utf-8")
    # -9n as gzip does: no name, no time, so the same changelog gives the same bytes.
    with open(output, "wb") as raw, gzip.GzipFile(fileobj=raw, mode="wb", compresslevel=9,
                                                  filename="", mtime=0) as out:
        out.write(data)


if __name__ == "__main__":
    main()
