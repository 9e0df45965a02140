# Shared by the command-line test scripts (sourced): the scratch folder, the pass/fail counters
# and check.
# usage (in a script): bin=$1; src=$2; . "$(dirname "$0")/lib.sh"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
pass=0
fail=0
check() {  # name, condition (a command)
  local name=$1
  shift
  if "$@"; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: $name"; fi
}
