#!/usr/bin/env bash
# The source tree's layers point down only: a file in synth/<layer>/ includes headers of its own
# layer and of the layers before it in this order, never of one after it (issue 19).
#   foundation  value types every layer uses (expression vectors, intervals, budget, diagnostics,
#               report rows)
#   symbolic    GiNaC algorithms (Lie derivatives, zero test, polynomial rings, expression DAG)
#   front       the model: parser, binding, Model
#   certify     enclosures and certificates (Arb), definedness
#   analysis    the analysis pipeline (observability, canonical form, ...)
#   designs     observer designs and their registry, the observer description (ObserverSpec)
#   emit        C++ and C99 back ends
#   app         commands: synthesize, simulate, reports, worker
# synth/main.cpp sits on top. Usage: layering.sh SOURCE_DIR; prints every offending include.
set -u
src=${1:?usage: layering.sh SOURCE_DIR}
layers=(foundation symbolic front certify analysis designs emit app)
rank() {
  local i
  for i in "${!layers[@]}"; do [[ ${layers[$i]} == "$1" ]] && { echo "$i"; return; }; done
  echo -1
}
status=0
checked=0
for layer in "${layers[@]}"; do
  own=$(rank "$layer")
  [[ -d $src/synth/$layer ]] || { echo "layering: missing layer synth/$layer"; status=1; continue; }
  for file in "$src"/synth/"$layer"/*; do
    checked=$((checked + 1))
    while IFS=: read -r line text; do
      target=$(sed -E 's|.*#include "([a-z_]+)/.*|\1|' <<<"$text")
      r=$(rank "$target")
      if ((r > own)); then
        echo "${file#"$src"/}:$line: $layer includes $target (a layer above it): $text"
        status=1
      fi
    done < <(grep -n '^#include "[a-z_]*/' "$file")
  done
done
# Every folder of synth/ is a known layer (a new folder must be placed in the order above).
for dir in "$src"/synth/*/; do
  name=$(basename "$dir")
  [[ $(rank "$name") -ge 0 ]] || { echo "layering: synth/$name is not in the layer order"; status=1; }
done
echo "layering: $checked files checked, $([[ $status == 0 ]] && echo "no include runs up a layer" || echo "violations above")"
exit $status
