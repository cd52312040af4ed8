#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Checks that every source file in git (C++, TypeScript and JavaScript, Python, shell, CMake, the
# Makefile, the viewer's page) names btfkit's licence in its first three lines:
#   // SPDX-License-Identifier: MIT     (C++, TS, JS)
#   # SPDX-License-Identifier: MIT      (Python, shell, CMake, Makefile; after a #! line)
#   <!-- SPDX-License-Identifier: MIT --> (HTML, after <!doctype html>)
# `make format-check` (and so `make test`) runs it. Exits 1 naming the files without it.
set -euo pipefail
cd "$(dirname "$0")/.."

missing=()
count=0
while IFS= read -r file; do
  [[ -f $file ]] || continue  # deleted in the working tree
  count=$((count + 1))
  head -n 3 "$file" | grep -q 'SPDX-License-Identifier: MIT' || missing+=("$file")
done < <(git ls-files --cached --others --exclude-standard |
  grep -E '\.(cpp|h|ts|mjs|js|sh|py|pyi|cmake|in|html)$|(^|/)CMakeLists\.txt$|(^|/)Makefile$|^\.ci/run$')

if ((${#missing[@]})); then
  echo "check_spdx.sh: ${#missing[@]} source files do not say 'SPDX-License-Identifier: MIT' in their first lines:" >&2
  printf '  %s\n' "${missing[@]}" >&2
  exit 1
fi
echo "spdx-check: $count source files name their licence (MIT)"
