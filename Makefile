# Top-level entry points. CMake does the real build in build/.
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release
PREFIX ?= /usr/local

.PHONY: all deps configure install run bake test bench bench-batch bench-http bench-walk experiments accuracy clean asan tsan valgrind fuzz test-scale

all: configure
	cmake --build $(BUILD) -j $(JOBS)

deps:
	@./scripts/install-deps.sh

configure: deps
	@test -f $(BUILD)/CMakeCache.txt || cmake -S . -B $(BUILD) $(CMAKE_FLAGS)

# The commands, libgi (libgi.so and libgi.a), its headers, gi.pc and the
# CMake package (find_package(gi)) under PREFIX; DESTDIR stages the tree
# for packaging (make install DESTDIR=/tmp/pkgroot). The library folder
# (lib/ or lib/<multiarch>/ for /usr) is chosen when build/ is configured.
install: all
	DESTDIR="$(DESTDIR)" cmake --install $(BUILD) --prefix "$(PREFIX)"

# The main job: serve the default catalog (the procedural city, and the
# shared scenes when present) on 127.0.0.1:8080 until Ctrl-C.
run: all
	$(BUILD)/bin/gi-server --config configs/gi-server.ini

# One bake on the command line: the embedded city at its default viewpoint.
bake: all
	@mkdir -p out
	$(BUILD)/bin/gi-bake city --exr out/city-probe.exr --vdb out/city-cascades.vdb

test: all
	@./scripts/install-deps.sh test
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# Benchmarks print figures; they never decide pass or fail.
bench: all
	./tests/bench/run-bench.sh $(BUILD)
	./tests/bench/specular-bench.sh $(BUILD)
	./tests/bench/render-bench.sh $(BUILD)
	./tests/bench/speedup.sh $(BUILD)
	./tests/bench/lights-bench.sh $(BUILD)

# Batch probe grids (issue 13): Munich street-level probes at 4 m, 2 m above
# the ground, on 2 threads: probes, tiles, time, probes/s, peak RSS. Figures only.
bench-batch: all
	./tests/bench/batch-bench.sh $(BUILD)

# HTTP load test (wrk): starts gi-server on an ephemeral port with the default
# config, benches cached and uncached lighting requests, stops the server.
bench-http: all
	./tests/bench/http-bench.sh --start $(BUILD)/bin/gi-server configs/gi-server.ini

# Moving viewpoints (issue 12): a street walk (1.4 m/s) and a drive (14 m/s)
# through the city at default quality, 10 Hz for 60 s, one cascade moved
# along each (gi_cascade_move) against cold bakes at sampled grid shifts:
# speed-up, drift and popping against the goals, then the same paths through
# gi-server with gi-client walk when it has that command. About 10-15 min on
# 2 cores; GI_WALK_QUICK=1 runs a seconds-long version. Figures only.
bench-walk: all
	./tests/bench/walk-bench.sh $(BUILD)

# The paper's tables (docs/experiments.md and docs/experiments-walk.png):
# voxels, memory against dense and OpenVDB grids, stage times and the
# dynamic update for the city at 600/1500/5000 m and Munich, and the walk
# chart (from bench-walk's out/, run first when missing). gnuplot-nox comes
# with deps. The reading is hand-written in docs/experiments-reading.md.
experiments: all
	./tests/bench/experiments.sh $(BUILD)

# The accuracy/time report: sweeps every quality knob and the path tracer
# against a path-traced reference (cached in out/accuracy), then the
# workloads at equal error (20/1000/10000 probes, a panorama, the camera
# views, Munich's aerial view, Blender Cycles on it when `blender` is on
# PATH), and regenerates docs/accuracy.md, docs/accuracy.png,
# docs/accuracy.csv and docs/workloads.csv/.jsonl. Long: the first run
# renders every reference (later runs read them from out/accuracy).
accuracy: all
	@mkdir -p out/accuracy docs
	$(BUILD)/bin/gi-accuracy --out out/accuracy --md docs/accuracy.md --png docs/accuracy.png \
	    --notes docs/accuracy-notes.md
	cp out/accuracy/accuracy.csv docs/accuracy.csv.tmp && mv docs/accuracy.csv.tmp docs/accuracy.csv
	cp out/accuracy/workloads.csv docs/workloads.csv.tmp && mv docs/workloads.csv.tmp docs/workloads.csv
	cp out/accuracy/workloads.jsonl docs/workloads.jsonl.tmp && mv docs/workloads.jsonl.tmp docs/workloads.jsonl

# Sanitizer builds: the whole ctest suite under ASan+UBSan and under TSan,
# each in its own build folder. Any report fails the run. Suppressions
# (tests/sanitize/*.supp) name third-party libraries only.
SAN_SUPP := $(CURDIR)/tests/sanitize
ASAN_FLAGS := -fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer
TSAN_FLAGS := -fsanitize=thread -fno-omit-frame-pointer

asan: deps
	cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Release -DCMAKE_C_FLAGS="$(ASAN_FLAGS)" \
	  -DCMAKE_CXX_FLAGS="$(ASAN_FLAGS)" -DCMAKE_EXE_LINKER_FLAGS="$(ASAN_FLAGS)"
	cmake --build build-asan -j $(JOBS)
	cd build-asan && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:strict_string_checks=1 \
	  LSAN_OPTIONS=suppressions=$(SAN_SUPP)/lsan.supp:print_suppressions=0 \
	  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 ctest --output-on-failure -j $(JOBS)

tsan: deps
	cmake -S . -B build-tsan -DCMAKE_BUILD_TYPE=Release -DCMAKE_C_FLAGS="$(TSAN_FLAGS)" \
	  -DCMAKE_CXX_FLAGS="$(TSAN_FLAGS)" -DCMAKE_EXE_LINKER_FLAGS="$(TSAN_FLAGS)" -DGI_TEST_SLOWDOWN=4
	cmake --build build-tsan -j $(JOBS)
	cd build-tsan && TSAN_OPTIONS=suppressions=$(SAN_SUPP)/tsan.supp:halt_on_error=1:second_deadlock_stack=1 \
	  setarch $$(uname -m) -R ctest --output-on-failure -j $(JOBS)

# valgrind memcheck on a small bake (a closed box with an area light, EXR
# and VDB written); any error or definite leak fails.
valgrind: all
	./scripts/install-deps.sh valgrind
	./tests/sanitize/valgrind-bake.sh $(BUILD)/bin/gi-bake

# Fuzzing (opt-in, clang + libFuzzer + ASan/UBSan): each target in
# FUZZ_TARGETS runs FUZZ_SECONDS from its seed corpus (tests/fuzz/corpus/),
# growing build-fuzz/corpus/<name>; crashes land in build-fuzz/artifacts/<name>/
# and fail the run. The seed corpus is replayed in every `make test`.
FUZZ_SECONDS ?= 60
FUZZ_TARGETS ?= scene request config
FUZZ_FLAGS := -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer

fuzz:
	./scripts/install-deps.sh fuzz
	CC=clang-14 CXX=clang++-14 cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=Release -DGI_FUZZ=ON \
	  -DCMAKE_C_FLAGS="$(FUZZ_FLAGS)" -DCMAKE_CXX_FLAGS="$(FUZZ_FLAGS)" \
	  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined"
	cmake --build build-fuzz -j $(JOBS) --target $(addprefix fuzz_,$(FUZZ_TARGETS))
	@set -e; for t in $(FUZZ_TARGETS); do \
	  mkdir -p build-fuzz/corpus/$$t build-fuzz/artifacts/$$t; \
	  echo "fuzz_$$t: $(FUZZ_SECONDS) s"; \
	  build-fuzz/fuzz/fuzz_$$t -max_total_time=$(FUZZ_SECONDS) -timeout=10 -rss_limit_mb=2048 \
	    -artifact_prefix=build-fuzz/artifacts/$$t/ build-fuzz/corpus/$$t tests/fuzz/corpus/$$t; \
	done

# Scale-out tests (opt-in, issue 14), each tests/scale/NAME.sh for NAME in
# SCALE_TESTS: nginx = real nginx (configs/nginx/gi.conf) in front of three
# gi-server replicas, about a minute; slurm = a one-node Slurm cluster
# (munged, slurmctld, slurmd, as root) running configs/slurm/bake-array.sbatch
# for a 4-shard Cornell grid, then a cancelled task resubmitted, about a
# minute. Installs what they need when missing;
# a test that still cannot run exits 77 and is reported as SKIPPED.
SCALE_TESTS ?= nginx slurm
test-scale: all
	@./scripts/install-deps.sh $(SCALE_TESTS) || echo "test-scale: WARNING: could not install $(SCALE_TESTS)"
	@for t in $(SCALE_TESTS); do \
	  rc=0; ./tests/scale/$$t.sh $(abspath $(BUILD)) || rc=$$?; \
	  if [ $$rc = 77 ]; then echo "test-scale: SKIPPED $$t (see above)"; elif [ $$rc != 0 ]; then exit $$rc; fi; \
	done

clean:
	rm -rf $(BUILD) build-asan build-tsan build-fuzz out
