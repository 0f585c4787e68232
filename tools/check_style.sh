#!/usr/bin/env bash
# The habits of docs/contributing.md that a program can check:
#   tools/check_style.sh [BASE]
# 1. every tracked *.h / *.cc under src include tools test bench python (the fuzz corpus left
#    out) is formatted as the repository's .clang-format says (clang-format --dry-run --Werror);
# 2. with BASE (a commit, e.g. origin/main), the subject of every commit in BASE..HEAD is at
#    most 72 characters and, when the message has more lines, followed by a blank line.
# Prints each offending file or commit and exits 1 when there is any, 0 otherwise.
# Set CLANG_FORMAT to use another clang-format binary.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
clang_format="${CLANG_FORMAT:-clang-format}"
max_subject=72
failed=0

check_format() {
  if ! command -v "$clang_format" >/dev/null; then
    echo "check_style: '$clang_format' not found (Debian: apt-get install clang-format)" >&2
    exit 2
  fi
  local files=() bad=0 file
  while IFS= read -r -d '' file; do
    files+=("$file")
  done < <(git ls-files -z -- 'src/*.h' 'src/*.cc' 'include/*.h' 'include/*.cc' 'tools/*.h' \
    'tools/*.cc' 'test/*.h' 'test/*.cc' 'bench/*.h' 'bench/*.cc' 'python/*.cc' \
    ':!:test/fuzz/corpus/*')
  # One run over every file; each difference is reported as "FILE:LINE:COL: error: ...".
  local differing
  differing="$("$clang_format" --style=file --dry-run --Werror "${files[@]}" 2>&1 |
    sed -n 's/^\([^:]*\):[0-9]*:[0-9]*: error: .*/\1/p' | sort -u)" || true
  for file in $differing; do
    echo "format: $file differs from .clang-format (fix: $clang_format -i $file)"
    bad=$((bad + 1))
  done
  echo "format: $bad of ${#files[@]} files differ from .clang-format"
  [ "$bad" -eq 0 ] || failed=1
}

check_commit_messages() {
  local base="$1" bad=0 count=0 commit subject second
  git rev-parse --verify --quiet "$base^{commit}" >/dev/null || {
    echo "check_style: '$base' is no commit" >&2
    exit 2
  }
  while IFS= read -r commit; do
    count=$((count + 1))
    subject="$(git log -1 --format=%s "$commit")"
    second="$(git log -1 --format=%B "$commit" | sed -n 2p)"
    if [ "${#subject}" -gt "$max_subject" ]; then
      echo "commit ${commit:0:12}: subject has ${#subject} characters (at most $max_subject):" \
        "${subject:0:60}..."
      bad=$((bad + 1))
    elif [ -n "$second" ]; then
      echo "commit ${commit:0:12}: no blank line after the subject: $subject"
      bad=$((bad + 1))
    fi
  done < <(git rev-list --no-merges "$base..HEAD")
  echo "commits: $bad of $count since $base break the message rule"
  [ "$bad" -eq 0 ] || failed=1
}

check_format
if [ $# -ge 1 ]; then
  check_commit_messages "$1"
fi
exit "$failed"
