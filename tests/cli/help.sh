# help.sh: --help exits 0 and names every option; --version exits 0.
. "$(dirname "$0")/common.sh"

out=$("$BIN" --help); rc=$?
[ $rc -eq 0 ] && pass "--help exits 0" || fail "--help exited $rc"
for opt in --at --up --levels --res --voxel --cones --bounces --samples --probe-samples --threads \
           --exr --half --vdb --vdb-faces --json --probes --sun --sky --point --spot --no-default-lights \
           --ao --effect --render --png --render-samples --render-stride --city-extent --city-seed --city-detail --help --version \
           --grid --region --above-ground --shard --resume --manifest --max-tiles --lightmap --uv-out --texel --atlas --tile --own-charts; do
  printf '%s\n' "$out" | grep -q -e "$opt\\b" || fail "--help does not mention $opt"
done
printf '%s\n' "$out" | grep -q "Examples" || fail "--help has no examples"
pass "--help mentions every option"

# --grid's help names the options it refuses, and each is refused (exit 2, naming it) before the
# scene loads: --half exited 2 with --grid while neither --help nor README said so.
grid_help=$(printf '%s\n' "$out" | grep -A5 -e "^  --grid S")
printf '1 2 3\n' > "$T/p.txt"
for args in "--half" "--vdb-faces --vdb $T/g.vdb" "--at 1,2,3" "--probes $T/p.txt" \
            "--render 0,1,5,0,1,0,60,8,8 --png $T/g.png"; do
  opt=${args%% *}
  printf '%s\n' "$grid_help" | grep -q -e "$opt\\b" || fail "--help's --grid does not say $opt is refused"
  # shellcheck disable=SC2086
  "$BIN" city --grid 50 --exr "$T/g.exr" $args > /dev/null 2> "$T/err"; rc=$?
  [ $rc -eq 2 ] && grep -q -e "$opt" "$T/err" && grep -q -e "with --grid\|--grid: cannot" "$T/err" \
    && pass "--grid $args -> 2: $(head -n 1 "$T/err")" \
    || fail "--grid $args exited $rc: $(cat "$T/err")"
done

v=$("$BIN" --version); rc=$?
[ $rc -eq 0 ] && printf '%s\n' "$v" | grep -q '^gi-bake ' && pass "--version" || fail "--version: rc $rc, '$v'"
finish
