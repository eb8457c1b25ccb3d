#!/usr/bin/env bash
# Formats every C++ file of the repository with clang-format and the repository's
# .clang-format (Debian 12's clang-format 14), or, with --check, fails listing the files that
# are not formatted (scripts/test.sh runs the check, so CI does).
#
#   scripts/format.sh           # rewrite the files in place
#   scripts/format.sh --check   # change nothing; exit 1 if a file needs formatting
set -euo pipefail
cd "$(dirname "$0")/.."
if git rev-parse --is-inside-work-tree > /dev/null 2>&1; then
    mapfile -t files < <(git ls-files '*.cpp' '*.hpp' '*.h')
else # a copy without git: the project's source folders
    mapfile -t files < <(find module integration samples tests \( -name '*.cpp' -o -name '*.hpp' -o -name '*.h' \) | sort)
fi
if [[ "${1:-}" == "--check" ]]; then
    bad=()
    for f in "${files[@]}"; do
        clang-format --dry-run --Werror "$f" > /dev/null 2>&1 || bad+=("$f")
    done
    if ((${#bad[@]})); then
        echo "format: ${#bad[@]} file(s) differ from .clang-format (run scripts/format.sh):" >&2
        printf '  %s\n' "${bad[@]}" >&2
        exit 1
    fi
    echo "format: ${#files[@]} files match .clang-format"
else
    clang-format -i "${files[@]}"
fi
