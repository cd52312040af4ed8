#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Writes docs/licences.md: the licences of what btfkit's Debian package links and holds, read
from the Debian packages' own copyright files (and the npm packages' package.json), not guessed.

    scripts/licences.py build/package/btfkit_0.2.0_amd64.deb build/package > docs/licences.md

From the .deb: its Depends (what dpkg-shlibdeps found the programs link, and Python) and the
closure of shared libraries `ldd` lists for its programs; from the package build folder: the
headers compiled into them (`ninja -t deps`), whose packages' code is in the binaries too.
CTest's Install.deb checks that docs/licences.md names every package of the Depends field.
"""
import json
import os
import re
import subprocess
import sys
import tempfile

DOC = "/usr/share/doc"


def run(*args):
    return subprocess.run(args, check=True, capture_output=True, text=True).stdout


def owners(paths):
    """{path: package} for files that a Debian package installed (dpkg -S), in batches."""
    result = {}
    paths = sorted(set(paths))
    for i in range(0, len(paths), 200):
        out = subprocess.run(["dpkg", "-S", *paths[i:i + 200]], capture_output=True, text=True)
        for line in out.stdout.splitlines():
            packages, _, path = line.partition(": ")
            if path in paths:
                # "libfoo:amd64, libfoo-dev:amd64: /path": the first owner.
                result[path] = packages.split(",")[0].split(":")[0].strip()
    return result


def licences(package):
    """(main licence, [other licences], machine-readable?) from the package's copyright file."""
    path = os.path.join(DOC, package, "copyright")
    try:
        text = open(path, encoding="utf-8", errors="replace").read()
    except OSError:
        return None, [], False
    first = re.split(r"\n\s*\n", text.lstrip(), maxsplit=1)[0]
    if not re.search(r"^Format(-Specification)?:", first, re.M):
        return None, [], False
    main, others = None, []
    for paragraph in re.split(r"\n\s*\n", text):
        files = re.search(r"^Files:\s*(.*)$", paragraph, re.M)
        lic = re.search(r"^License:\s*(.+)$", paragraph, re.M)
        if not files or not lic:
            continue
        name = lic.group(1).strip()
        if main is None and files.group(1).split()[:1] == ["*"]:
            main = name
        elif name not in others:
            others.append(name)
    if main is None and others:
        main = others.pop(0)
    return main, [o for o in others if o != main], True


# What a free-form copyright file is searched for: the licences it mentions, by their names.
MENTIONS = [
    ("GNU Lesser General Public License|GNU Library General Public License|\\bLGPL", "LGPL"),
    ("(?<!Lesser )(?<!Library )General Public License|\\bGPL\\b", "GPL"),
    ("GCC Runtime Library Exception", "GCC Runtime Library Exception"),
    ("Python Software Foundation License|\\bPSF\\b", "PSF"),
    ("Apache License", "Apache"),
    ("\\bBSD\\b|Redistribution and use in source and binary forms", "BSD"),
    ("\\bMIT\\b|Permission is hereby granted, free of charge", "MIT"),
]


def mentioned(package):
    try:
        text = open(os.path.join(DOC, package, "copyright"), encoding="utf-8",
                    errors="replace").read()
    except OSError:
        return []
    text = re.sub(r"\s+", " ", text)
    return [name for pattern, name in MENTIONS if re.search(pattern, text)]


def licence_cell(package):
    main, others, readable = licences(package)
    if not readable:
        names = mentioned(package)
        said = "mentions " + ", ".join(names) if names else "names no licence we search for"
        return f"free-form copyright file ({DOC}/{package}/copyright), which {said}"
    cell = main or "?"
    if others:
        cell += " (parts: " + ", ".join(others) + ")"
    return cell.replace("|", "\\|")


def depends(deb):
    field = run("dpkg-deb", "-f", deb, "Depends")
    names = []
    for item in field.split(","):
        name = item.split("|")[0].split("(")[0].strip()
        if name and name not in names:
            names.append(name)
    return names


def linked_closure(deb):
    """Packages of every shared library the package's ELF files load (ldd, from an unpacked copy)."""
    with tempfile.TemporaryDirectory() as root:
        run("dpkg-deb", "-x", deb, root)
        libraries = set()
        for folder, _, files in os.walk(root):
            for name in files:
                path = os.path.join(folder, name)
                with open(path, "rb") as f:
                    if f.read(4) != b"\x7fELF":
                        continue
                out = subprocess.run(["ldd", path], capture_output=True, text=True).stdout
                for line in out.splitlines():
                    m = re.search(r"=> (/\S+)", line)
                    if m and not m.group(1).startswith(root):
                        libraries.add(os.path.realpath(m.group(1)))
    return sorted(set(owners(libraries).values()))


def compiled_headers(build):
    """Packages whose headers the package build compiled (ninja's record of each object's deps)."""
    out = run("ninja", "-C", build, "-t", "deps")
    headers = {line.strip() for line in out.splitlines() if line.startswith("    /usr/")}
    return sorted(set(owners({os.path.realpath(h) for h in headers} | headers).values()))


def npm_packages(web):
    manifest = json.load(open(os.path.join(web, "package.json")))
    rows = []
    for name in sorted(manifest.get("dependencies", {})):
        meta = json.load(open(os.path.join(web, "node_modules", name, "package.json")))
        rows.append((name, meta.get("version", "?"), meta.get("license", "?")))
    return rows


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    deb, build = sys.argv[1:]
    source = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    direct = depends(deb)
    closure = [p for p in linked_closure(deb) if p not in direct]
    headers = [p for p in compiled_headers(build) if p not in direct and p not in closure]

    out = []
    out.append("# Licences\n")
    out.append(
        "btfkit itself is under the MIT licence (`LICENSE`; every source file says "
        "`SPDX-License-Identifier: MIT`). The tables below are what its Debian package links "
        "and holds, each with the licences its Debian package's copyright file declares "
        "(the `Files: *` paragraph first, then the licences of parts), made by "
        f"`scripts/licences.py {os.path.basename(deb)} build/package` from "
        f"{DOC}/PACKAGE/copyright; CTest's Install.deb checks that every package of the "
        "`Depends` field is here.\n")
    out.append("## The package's `Depends` (what its programs and module link directly)\n")
    out.append("| Debian package | licence |\n|---|---|")
    out += [f"| {p} | {licence_cell(p)} |" for p in direct]
    out.append("\n## Loaded through those (the rest of the shared libraries `ldd` lists)\n")
    by_licence = {}
    for p in closure:
        by_licence.setdefault(licence_cell(p), []).append(p)
    out.append("| licence | Debian packages |\n|---|---|")
    out += [f"| {lic} | {', '.join(ps)} |" for lic, ps in sorted(by_licence.items())]
    out.append("\n## Compiled in from headers (header-only libraries and inline code)\n")
    out.append("| Debian package | licence |\n|---|---|")
    out += [f"| {p} | {licence_cell(p)} |" for p in headers]
    out.append("\n## Bundled into the web viewer (share/btfkit/web, from npm)\n")
    out.append("| npm package | version | licence (its package.json) |\n|---|---|---|")
    out += [f"| {n} | {v} | {lic} |" for n, v, lic in npm_packages(os.path.join(source, "web"))]
    print("\n".join(out))


if __name__ == "__main__":
    main()
