# Top-level entry points. CMake does the real build in build/.
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release

.PHONY: all deps configure run test bench accuracy clean

all: configure
	cmake --build $(BUILD) -j $(JOBS)

deps:
	@./scripts/install-deps.sh

configure: deps
	@test -f $(BUILD)/CMakeCache.txt || cmake -S . -B $(BUILD) $(CMAKE_FLAGS)

# The main job: bake the embedded procedural city at its default viewpoint.
run: all
	@mkdir -p out
	$(BUILD)/bin/gi-bake city --exr out/city-probe.exr --vdb out/city-cascades.vdb

test: all
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# Benchmarks print figures; they never decide pass or fail.
bench: all
	./tests/bench/run-bench.sh $(BUILD)

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
