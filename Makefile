# Top-level entry points. CMake does the real build in build/.
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release

.PHONY: all deps configure run bake test bench bench-http accuracy clean

all: configure
	cmake --build $(BUILD) -j $(JOBS)

deps:
	@./scripts/install-deps.sh

configure: deps
	@test -f $(BUILD)/CMakeCache.txt || cmake -S . -B $(BUILD) $(CMAKE_FLAGS)

# The main job: serve the default catalog (the procedural city, and the
# shared scenes when present) on 127.0.0.1:8080 until Ctrl-C.
run: all
	$(BUILD)/bin/gi-server --config configs/gi-server.ini

# One bake on the command line: the embedded city at its default viewpoint.
bake: all
	@mkdir -p out
	$(BUILD)/bin/gi-bake city --exr out/city-probe.exr --vdb out/city-cascades.vdb

test: all
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# Benchmarks print figures; they never decide pass or fail.
bench: all
	./tests/bench/run-bench.sh $(BUILD)

# HTTP load test (wrk): starts gi-server on an ephemeral port with the default
# config, benches cached and uncached lighting requests, stops the server.
bench-http: all
	./tests/bench/http-bench.sh --start $(BUILD)/bin/gi-server configs/gi-server.ini

# The accuracy/time report: sweeps every quality knob and the path tracer
# against a path-traced reference (cached in out/accuracy) and regenerates
# docs/accuracy.md, docs/accuracy.png and docs/accuracy.csv. Several minutes.
accuracy: all
	@mkdir -p out/accuracy docs
	$(BUILD)/bin/gi-accuracy --out out/accuracy --md docs/accuracy.md --png docs/accuracy.png \
	    --notes docs/accuracy-notes.md
	cp out/accuracy/accuracy.csv docs/accuracy.csv.tmp && mv docs/accuracy.csv.tmp docs/accuracy.csv

clean:
	rm -rf $(BUILD) out
