#!/usr/bin/env bash
# slurm.sh: the sharded grid bake on a real one-node Slurm cluster (issue 14).
#
# Starts munged (its own key and socket), slurmctld and slurmd in the
# foreground on this machine with a slurm.conf generated under a temporary
# folder (free ports, state and spool there too), then bakes a 4-shard
# probe grid of the Cornell box with configs/slurm/bake-array.sbatch:
#   1. the array and its merge job: every task and the merge COMPLETED, the
#      merged EXR and VDB byte-identical to the unsharded bake (cmp);
#   2. again into a fresh folder, task 0 cancelled (scancel) once it has
#      checkpointed a tile: the merge job is cancelled with it and writes
#      nothing; resubmitting just that task (ARRAY=0) resumes from its
#      checkpoints (manifest and progress lines: resumed = tiles saved
#      before the cancel, baked = the rest), and the new merge is still
#      byte-identical.
# Prints the cluster's start time, the bake and array wall times and the
# tiles of each run. Stops every daemon it started, by pid, on any exit.
# Exit 0 pass, 1 fail, 77 skip (not root, Slurm or munge missing or not
# starting, no shared scenes).
# Usage: tests/scale/slurm.sh [BUILD_DIR]
set -u
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
BUILD=${1:-$ROOT/build}
BAKE=$BUILD/bin/gi-bake
SBATCH_SCRIPT=$ROOT/configs/slurm/bake-array.sbatch
SCENE=${GI_SCENES_DIR:-$ROOT/../shared/scenes}/cornell-box/cornell-box.obj
PY=${PYTHON:-/usr/bin/python3}
SHARDS=4
# 19^3 probes in 3 x 3 x 3 tiles (7, 7, 7 and 6 per shard) of about 0.5 s
# each on one core: long enough to cancel a task between two tiles.
QUALITY="--grid 30 --voxel 10 --res 48 --levels 3 --bounces 1 --cones 8 --samples 4 --probe-samples 16"
TILES=27
VICTIM=0
VICTIM_TILES=7
# Two tasks at a time on two cores; the script's own --cpus-per-task=2
# would run them one after another.
JOB_ARGS="--cpus-per-task=1 --mem=1G"
START_TIMEOUT_S=60
JOB_TIMEOUT_S=600

skip() { echo "SKIP: $*"; exit 77; }
[ "$(id -u)" = 0 ] || skip "needs root (slurmd runs jobs as root here: SlurmdUser=root)"
for b in munged mungekey slurmctld slurmd sbatch squeue scancel scontrol sinfo; do
  command -v "$b" > /dev/null 2>&1 || [ -x "/usr/sbin/$b" ] ||
    skip "$b is not installed (make test-scale installs it: apt-get install -y slurm-wlm munge)"
done
[ -f "$SCENE" ] || skip "no Cornell box at $SCENE (set GI_SCENES_DIR)"
[ -x "$BAKE" ] || { echo "FAIL: $BAKE not built (make all)"; exit 1; }
PATH=$PATH:/usr/sbin

T=$(mktemp -d /tmp/gi-scale-slurm.XXXXXX)
# munged wants every folder above its socket searchable by all.
chmod 755 "$T"
mkdir -p "$T/state" "$T/spool" "$T/log"
MUNGED_PID="" CTLD_PID="" SLURMD_PID=""
export SLURM_CONF=$T/slurm.conf

# stop PID NAME: SIGTERM, up to 10 s, then SIGKILL.
stop() {
  [ -n "$1" ] || return 0
  kill "$1" 2> /dev/null || return 0
  for _ in $(seq 1 100); do kill -0 "$1" 2> /dev/null || break; sleep 0.1; done
  if kill -0 "$1" 2> /dev/null; then
    echo "slurm.sh: $2 ($1) ignored SIGTERM, killing it"
    kill -9 "$1" 2> /dev/null
  fi
  wait "$1" 2> /dev/null
}
stop_all() {
  # Jobs first, while the daemons that run them are up.
  if [ -n "$CTLD_PID" ] && kill -0 "$CTLD_PID" 2> /dev/null; then
    # shellcheck disable=SC2046 # one word per job id
    scancel --quiet $(squeue -h -o %A 2> /dev/null | sort -u) 2> /dev/null
    for _ in $(seq 1 100); do [ -z "$(squeue -h 2> /dev/null)" ] && break; sleep 0.1; done
  fi
  stop "$SLURMD_PID" slurmd
  stop "$CTLD_PID" slurmctld
  stop "$MUNGED_PID" munged
  MUNGED_PID="" CTLD_PID="" SLURMD_PID=""
}
cleanup() { stop_all; rm -rf "$T"; }
trap cleanup EXIT
trap 'exit 1' INT TERM
fail() { echo "FAIL: $*"; echo "--- logs in $T kept"; trap - EXIT; stop_all; exit 1; }
# cannot_start WHAT: Slurm is installed but does not come up here.
cannot_start() {
  echo "slurm.sh: $1; last log lines:"
  tail -n 5 "$T"/log/*.log 2> /dev/null | sed 's/^/  /'
  stop_all
  skip "$1"
}
now_ms() { echo $(( $(date +%s%N) / 1000000 )); }
secs() { awk -v ms="$1" 'BEGIN { printf "%.1f", ms / 1000 }'; }

# ---- the cluster -----------------------------------------------------------------
t0=$(now_ms)
mungekey --create --keyfile="$T/munge.key" 2> "$T/log/mungekey.log" || cannot_start "mungekey could not create a key"
munged -F --socket="$T/munge.sock" --key-file="$T/munge.key" --pid-file="$T/munged.pid" \
  --seed-file="$T/munged.seed" --log-file="$T/log/munged.log" > /dev/null 2>&1 &
MUNGED_PID=$!
for _ in $(seq 1 50); do [ -S "$T/munge.sock" ] && break; sleep 0.1; done
[ -S "$T/munge.sock" ] || cannot_start "munged did not start"

HOST=$(hostname -s)
read -r CTLD_PORT SLURMD_PORT < <($PY -c '
import socket
ss = [socket.socket() for _ in range(2)]
for s in ss: s.bind(("", 0))
print(*[s.getsockname()[1] for s in ss])')
# 90% of the memory: slurmd drains a node whose RealMemory is above what it finds.
MEM_MB=$(awk '/^MemTotal:/ { printf "%d", $2 / 1024 * 0.9 }' /proc/meminfo)
cat > "$SLURM_CONF" <<EOF
ClusterName=giscale
SlurmctldHost=$HOST
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$T/munge.sock
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$T/state
SlurmdSpoolDir=$T/spool
SlurmctldPidFile=$T/slurmctld.pid
SlurmdPidFile=$T/slurmd.pid
SlurmctldLogFile=$T/log/slurmctld.log
SlurmdLogFile=$T/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
NodeName=$HOST CPUs=$(nproc) RealMemory=$MEM_MB State=UNKNOWN
PartitionName=gi Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
slurmctld -D -f "$SLURM_CONF" > "$T/log/slurmctld.out" 2>&1 &
CTLD_PID=$!
slurmd -D -f "$SLURM_CONF" > "$T/log/slurmd.out" 2>&1 &
SLURMD_PID=$!
state=""
for _ in $(seq 1 $((START_TIMEOUT_S * 10))); do
  state=$(sinfo -h -n "$HOST" -o %T 2> /dev/null)
  [ "$state" = idle ] && break
  kill -0 "$CTLD_PID" 2> /dev/null || break
  kill -0 "$SLURMD_PID" 2> /dev/null || break
  sleep 0.1
done
[ "$state" = idle ] || cannot_start "the node is not idle after ${START_TIMEOUT_S} s (state '$state')"
echo "slurm: $(sinfo -V) one-node cluster ($HOST, $(nproc) CPUs, ports $CTLD_PORT/$SLURMD_PORT) idle after" \
     "$(secs $(( $(now_ms) - t0 ))) s"

# ---- the unsharded bake ------------------------------------------------------------
t0=$(now_ms)
# shellcheck disable=SC2086
"$BAKE" "$SCENE" $QUALITY --threads 0 --exr "$T/full.exr" --vdb "$T/full.vdb" > "$T/full.out" 2> "$T/full.err" ||
  { cat "$T/full.err"; fail "the unsharded bake"; }
FULL_MS=$(( $(now_ms) - t0 ))
grep -q "$TILES tiles ($TILES baked" "$T/full.out" || fail "the unsharded bake: $(cat "$T/full.out")"

# submit OUT [ARRAY]: the shards and the merge through the shipped script; sets JID and MID.
submit() {
  local out
  out=$(SCENE=$SCENE OUT=$1 GRID_ARGS=$QUALITY SHARDS=$SHARDS GI_BAKE=$BAKE ARRAY=${2:-} SBATCH_ARGS=$JOB_ARGS \
        bash "$SBATCH_SCRIPT" submit 2>&1) || fail "submit: $out"
  JID=$(echo "$out" | sed -n 's/.*shards job \([0-9][0-9]*\).*/\1/p')
  MID=$(echo "$out" | sed -n 's/.*merge job \([0-9][0-9]*\).*/\1/p')
  [ -n "$JID" ] && [ -n "$MID" ] || fail "submit printed: $out"
}
# wait_gone JOB...: until squeue no longer lists them.
wait_gone() {
  local ids
  ids=$(IFS=,; echo "$*")
  for _ in $(seq 1 $((JOB_TIMEOUT_S * 10))); do
    [ -z "$(squeue -h -j "$ids" 2> /dev/null)" ] && return 0
    sleep 0.1
  done
  fail "jobs $ids still queued or running after $JOB_TIMEOUT_S s: $(squeue -h -j "$ids")"
}
# states JOB: the JobState of the job, or of each task of an array, by task id.
states() {
  scontrol -o show job "$1" | sed -n 's/.*ArrayTaskId=\([0-9]*\).*JobState=\([A-Z_]*\).*/\1:\2/p; t; s/.*JobState=\([A-Z_]*\).*/\1/p' | sort
}
# manifest_tiles FILE: "owned baked resumed total_ms"
manifest_tiles() {
  $PY -c 'import json, sys; m = json.load(open(sys.argv[1])); t = m["tiles"]
print(t["owned"], t["baked"], t["resumed"], round(m["timings_ms"]["total"]))' "$1"
}
same_as_full() { # same_as_full OUT WHAT
  cmp "$1/probes.exr" "$T/full.exr" || fail "$2: the merged EXR differs from the unsharded bake's"
  cmp "$1/probes.vdb" "$T/full.vdb" || fail "$2: the merged VDB differs from the unsharded bake's"
}

# ---- 1. the array and its merge ------------------------------------------------------
O1=$T/run1
t0=$(now_ms)
submit "$O1"
wait_gone "$JID" "$MID"
WALL1_MS=$(( $(now_ms) - t0 ))
want=""; for ((i = 0; i < SHARDS; i++)); do want="$want $i:COMPLETED"; done
got=$(states "$JID" | tr '\n' ' ')
[ "$got" = "${want# } " ] || fail "run 1: array tasks ended $got (see $O1/*.out)"
[ "$(states "$MID")" = COMPLETED ] || fail "run 1: merge job $(states "$MID") (see $O1/gi-bake-merge-$MID.out)"
same_as_full "$O1" "run 1"
per="" owned_sum=0 shard_s=""
for ((i = 0; i < SHARDS; i++)); do
  read -r owned baked resumed ms < <(manifest_tiles "$O1/shard-$i.json")
  [ "$baked" = "$owned" ] && [ "$resumed" = 0 ] || fail "run 1: shard $i baked $baked resumed $resumed of $owned"
  per="$per${per:+ + }$owned"; owned_sum=$((owned_sum + owned)); shard_s="$shard_s${shard_s:+, }$(secs "$ms")"
done
[ "$owned_sum" = $TILES ] || fail "run 1: the shards own $owned_sum tiles, the grid has $TILES"
echo "run 1: array $JID ($SHARDS tasks, tiles $per = $TILES) and merge $MID: all COMPLETED in" \
     "$(secs "$WALL1_MS") s (each shard's gi-bake on 1 thread: $shard_s s; the unsharded bake on 2 threads:" \
     "$(secs "$FULL_MS") s); merged EXR and VDB byte-identical"

# ---- 2. a task cancelled mid-run, then resubmitted --------------------------------------
O2=$T/run2
t0=$(now_ms)
submit "$O2"
LOG=$O2/gi-bake-${JID}_$VICTIM.out
for _ in $(seq 1 $((JOB_TIMEOUT_S * 10))); do
  grep -q 'source=baked' "$LOG" 2> /dev/null && break
  sleep 0.1
done
grep -q 'source=baked' "$LOG" 2> /dev/null || fail "run 2: task $VICTIM printed no finished tile (see $LOG)"
scancel "${JID}_$VICTIM" || fail "run 2: scancel ${JID}_$VICTIM"
CANCEL_MS=$(( $(now_ms) - t0 ))
wait_gone "$JID" "$MID"
printed=$(grep -c 'source=baked' "$LOG")
# What the cancelled task left: its tiles (t mod SHARDS = VICTIM) checkpointed.
saved=$(ls "$O2/tiles" | sed -n 's/^tile-0*\([0-9][0-9]*\)\.bin$/\1/p' | awk -v n=$SHARDS -v v=$VICTIM '$1 % n == v' | wc -l)
got=$(states "$JID" | tr '\n' ' ')
want="$VICTIM:CANCELLED"; for ((i = 0; i < SHARDS; i++)); do [ $i = $VICTIM ] || want="$want $i:COMPLETED"; done
[ "$got" = "$(echo "$want" | tr ' ' '\n' | sort | tr '\n' ' ')" ] || fail "run 2: array tasks ended $got"
[ "$(states "$MID")" = CANCELLED ] || fail "run 2: the merge job is $(states "$MID"), not cancelled with its dependency"
[ ! -e "$O2/probes.exr" ] || fail "run 2: a merge was written although task $VICTIM was cancelled"
[ "$saved" -ge 1 ] && [ "$saved" -lt $VICTIM_TILES ] ||
  fail "run 2: task $VICTIM checkpointed $saved of $VICTIM_TILES tiles before the cancel (want some, not all)"
echo "run 2: task ${JID}_$VICTIM cancelled $(secs "$CANCEL_MS") s after submitting, with $saved of $VICTIM_TILES" \
     "tiles checkpointed ($printed printed); the other tasks COMPLETED, merge $MID CANCELLED (dependency never satisfied)"

t0=$(now_ms)
submit "$O2" $VICTIM
wait_gone "$JID" "$MID"
WALL3_MS=$(( $(now_ms) - t0 ))
[ "$(states "$JID" | tr '\n' ' ')" = "$VICTIM:COMPLETED " ] || fail "run 2, resubmitted: task ended $(states "$JID")"
[ "$(states "$MID")" = COMPLETED ] || fail "run 2, resubmitted: merge job $(states "$MID")"
LOG=$O2/gi-bake-${JID}_$VICTIM.out
read -r owned baked resumed ms < <(manifest_tiles "$O2/shard-$VICTIM.json")
[ "$owned" = $VICTIM_TILES ] && [ "$resumed" = "$saved" ] && [ "$baked" = $((VICTIM_TILES - saved)) ] ||
  fail "run 2, resubmitted: manifest says owned $owned, baked $baked, resumed $resumed (saved before: $saved)"
[ "$(grep -c 'source=resumed' "$LOG")" = "$saved" ] && [ "$(grep -c 'source=baked' "$LOG")" = "$baked" ] ||
  fail "run 2, resubmitted: progress lines: $(grep -c 'source=resumed' "$LOG") resumed, $(grep -c 'source=baked' "$LOG") baked"
same_as_full "$O2" "run 2"
echo "run 2, task $VICTIM resubmitted (ARRAY=$VICTIM, array $JID, merge $MID): resumed $resumed and baked $baked of" \
     "$owned tiles (run 1: baked $owned), gi-bake $(secs "$ms") s, $(secs "$WALL3_MS") s with the merge;" \
     "merged EXR and VDB byte-identical"
stop_all
echo "PASS: Slurm job array + merge, cancel and resume"
