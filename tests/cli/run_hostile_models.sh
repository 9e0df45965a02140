#!/usr/bin/env bash
# Hostile but valid models (tests/models/hostile/, issue 20, and the minimised findings of
# fuzz/pipeline_fuzz.cpp): the main job and `check` on each end with the exit status its header
# expects (`# expect-exit:`), print every `# expect-stderr:` text and none of the
# `# reject-output:` texts (nor does the report), never exit 2 or die of a signal, and an exit 1
# leaves no file in the output folder.
# usage: run_hostile_models.sh OBSYNTH SOURCE_DIR
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib.sh"

header() {  # model, key: the values of "# key: value" lines
  sed -n "s/^# $2: //p" "$1"
}

run_model() {  # model
  local model=$1 name want args out log status
  name=$(basename "$model" .sym)
  want=$(header "$model" expect-exit)
  args=$(header "$model" args)
  out="$tmp/$name"
  log="$tmp/$name.log"
  # shellcheck disable=SC2086  # args are words
  timeout 300 "$bin" "$model" -o "$out/" $args >"$log" 2>&1
  status=$?
  check "$name: main job exits $want (got $status)" test "$status" = "$want"
  while IFS= read -r text; do
    check "$name: prints '$text'" grep -qF -- "$text" "$log"
  done < <(header "$model" expect-stderr)
  while IFS= read -r text; do
    check "$name: does not print '$text'" bash -c "! grep -qF -- '$text' '$log' $out/*.md 2>/dev/null"
  done < <(header "$model" reject-output)
  check "$name: no internal error" bash -c "! grep -q 'internal error' '$log'"
  if [ "$want" = 1 ]; then
    check "$name: nothing written on exit 1" bash -c "[ ! -e '$out' ] || [ -z \"\$(ls -A '$out')\" ]"
  fi
  timeout 300 "$bin" check "$model" >"$log.check" 2>&1
  status=$?
  check "$name: check exits 0 or 1 (got $status)" test "$status" -le 1
}

for model in "$src"/tests/models/hostile/*.sym; do run_model "$model"; done
echo "hostile models: $pass passed, $fail failed"
[ "$fail" = 0 ]
