# merge_wait.sh: the merge Job's init container (configs/k8s/merge-job.yaml),
# run here with the claim at $T/bake: it must not let the merge start on a
# previous run's shard manifests, and must let it start once this bake's
# shards are all there. It counted shard-*.json files, so a rerun on the
# same claim merged the old bake as soon as it was applied.
BIN=${1:?usage: sh merge_wait.sh path/to/gi-bake}
T=$(mktemp -d "${TMPDIR:-/tmp}/gi-k8s.XXXXXX")
trap '[ -n "${KEEP:-}" ] || rm -rf "$T"' EXIT INT TERM
python3 -c 'import yaml' 2> /dev/null || { echo "SKIP: no PyYAML"; exit 77; }
YAML="$(dirname "$0")/../../configs/k8s/merge-job.yaml"
python3 - "$YAML" "$T" "$BIN" > "$T/init.sh" <<'PY' || { echo "FAIL: no init container"; exit 1; }
import sys, yaml
d = yaml.safe_load(open(sys.argv[1]))
c = d["spec"]["template"]["spec"]["initContainers"][0]
script = " ".join(c["command"][2:] + c["args"]).replace("/tmp/", "@T@/").replace("/bake", "@T@/bake")
script = script.replace("@T@", sys.argv[2]).replace("sleep 10", "sleep 0.1").replace("gi-bake", sys.argv[3])
print(script)
PY
mkdir "$T/bake"
cat > "$T/bake/box.obj" <<'OBJ'
v 0 0 0
v 4 0 0
v 4 0 4
v 0 0 4
v 0 4 0
v 4 4 0
f 1 4 3 2
f 1 2 6 5
OBJ
export SHARDS=2 SCENE="$T/bake/box.obj" GRID_ARGS="--grid 2 --levels 2 --res 8 --cones 4 --probe-samples 4"
fails=0
# A previous run's manifests (another bake): the init container must keep waiting.
for i in 0 1; do printf '{\n  "kind": "gi-bake probe grid",\n  "bake_hash": "0123456789abcdef"\n}\n' \
  > "$T/bake/shard-$i.json"; done
timeout 3 sh -c "$(cat "$T/init.sh")" > /dev/null 2>&1; rc=$?
[ $rc -eq 124 ] && echo "ok: stale manifests of another bake: still waiting" \
  || { echo "FAIL: init container finished (rc $rc) on a previous bake's manifests"; fails=1; }
# This bake's shards: it must finish.
for i in 0 1; do
  # shellcheck disable=SC2086
  "$BIN" "$SCENE" $GRID_ARGS --shard $i/2 --exr "$T/bake/shard-$i.exr" --manifest "$T/bake/shard-$i.json" \
    > /dev/null 2>&1 || { echo "FAIL: shard $i"; fails=1; }
done
timeout 20 sh -c "$(cat "$T/init.sh")" > /dev/null 2> "$T/err"; rc=$?
[ $rc -eq 0 ] && echo "ok: this bake's manifests: the merge may start" \
  || { echo "FAIL: init container rc $rc on this bake's manifests: $(cat "$T/err")"; fails=1; }
exit $fails
