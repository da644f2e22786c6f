#!/bin/sh
# Test of cmake/git_commit.cmake (CTest build.git_commit): the header names the commit that is checked
# out, gains "-dirty" with a changed tracked file, follows a new commit without reconfiguring, and is not
# rewritten when nothing changed.
#   git_commit_test.sh CMAKE SCRIPT
set -eu
cmake=$1 script=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cd "$tmp"
git init -q repo
cd repo
git config user.email t@example.com
git config user.name t
echo a > f
git add f
git commit -q -m one
gen() { "$cmake" -DSRC="$tmp/repo" -DOUT="$tmp/h.hpp" -P "$script"; }
expect() {  # what the header must define
  grep -q "#define HP_GIT_COMMIT \"$1\"" "$tmp/h.hpp" || { echo "expected $1, got: $(cat "$tmp/h.hpp")"; exit 1; }
}
gen
one=$(git rev-parse --short=12 HEAD)
expect "$one"

touch -d '2000-01-01' "$tmp/h.hpp"
stamp=$(stat -c %Y "$tmp/h.hpp")
gen
[ "$(stat -c %Y "$tmp/h.hpp")" = "$stamp" ] || { echo "rewritten although the commit did not change"; exit 1; }
echo b > f
gen
expect "$one-dirty"
git commit -q -am two
gen
two=$(git rev-parse --short=12 HEAD)
[ "$two" != "$one" ]
expect "$two"
echo "ok: $one, $one-dirty, $two"
