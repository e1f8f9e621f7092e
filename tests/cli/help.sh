# help.sh: --help exits 0 and names every option; --version exits 0.
. "$(dirname "$0")/common.sh"

out=$("$BIN" --help); rc=$?
[ $rc -eq 0 ] && pass "--help exits 0" || fail "--help exited $rc"
for opt in --at --up --levels --res --voxel --cones --bounces --samples --probe-samples --threads \
           --exr --half --vdb --vdb-faces --json --probes --sun --sky --point --spot --no-default-lights \
           --ao --effect --render --png --render-samples --render-stride --city-extent --city-seed --city-detail --help --version \
           --grid --region --above-ground --shard --resume --manifest --lightmap --uv-out --texel --atlas --tile --own-charts; do
  printf '%s\n' "$out" | grep -q -e "$opt\\b" || fail "--help does not mention $opt"
done
printf '%s\n' "$out" | grep -q "Examples" || fail "--help has no examples"
pass "--help mentions every option"

v=$("$BIN" --version); rc=$?
[ $rc -eq 0 ] && printf '%s\n' "$v" | grep -q '^gi-bake ' && pass "--version" || fail "--version: rc $rc, '$v'"
finish
