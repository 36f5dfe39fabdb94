# Entry points for people and CI. Every target installs the Debian packages it needs first
# (a quick no-op when they are present), then configures and builds with CMake + Ninja.
BUILD ?= build
ASAN_BUILD ?= build-asan
JOBS ?= $(shell nproc)
DEMO_OUT ?= out/demo
CMAKE_FLAGS ?=
# The interpreter the Python package is built and installed for: Debian's, which has Debian's
# NumPy and pybind11 (another python3 first on PATH, e.g. pyenv's, has neither).
PYTHON ?= /usr/bin/python3

# CI turns warnings into errors.
ifeq ($(CI),true)
  CMAKE_FLAGS += -DSPACEWARP_WARNINGS_AS_ERRORS=ON
endif

.PHONY: all deps configure build python-install demo test sanitize bench bench-stream bench-view fuzz format clean

all: build

deps:
	./scripts/install-deps.sh

configure: deps
	cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release -DPython3_EXECUTABLE=$(PYTHON) $(CMAKE_FLAGS)

build: configure
	cmake --build $(BUILD) -j $(JOBS)

# Installs the Python package for $(PYTHON) (into its site folder, /usr/local/lib/python3.X/
# dist-packages for Debian's), so that `import spacewarp` works after `make demo` or `make test`.
python-install: build
	./scripts/install-python.sh $(BUILD) $(PYTHON)

demo: build python-install
	$(BUILD)/apps/spacewarp demo $(DEMO_OUT)

test: build python-install
	ctest --test-dir $(BUILD) --output-on-failure -j $(JOBS)

# The test suite under AddressSanitizer and UndefinedBehaviorSanitizer. -O1 -g1 (line tables
# only) halves the compile time of the OpenVDB-heavy files and still gives stack traces.
sanitize: deps
	cmake -S . -B $(ASAN_BUILD) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
	  -DSPACEWARP_SANITIZE=ON -DSPACEWARP_BUILD_BENCHMARKS=OFF $(CMAKE_FLAGS)
	cmake --build $(ASAN_BUILD) -j $(JOBS)
	ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	  ctest --test-dir $(ASAN_BUILD) --output-on-failure -j $(JOBS)

bench: build
	$(BUILD)/bench/spacewarp_bench --benchmark_repetitions=3 \
	  --benchmark_report_aggregates_only=true --benchmark_counters_tabular=true
	PYTHONPATH=$(BUILD)/python $(PYTHON) bench/python_overhead.py

# Streaming deform of a generated binary PLY of POINTS points (default 200M, ~2.4 GB, deleted
# afterwards) against a plain copy of the same file: wall time, throughput, peak memory.
bench-stream: build
	$(PYTHON) bench/stream_bench.py --spacewarp $(BUILD)/apps/spacewarp $(if $(POINTS),--points $(POINTS))

# `spacewarp view` in headless Chromium: drag-to-frame latency and server deform time for the
# armadillo (../shared/data; else the demo's bar) and generated clouds of SIZES million points.
bench-view: configure
	cmake --build $(BUILD) -j $(JOBS) --target spacewarp_cli spacewarp_web
	node bench/view_latency.mjs --spacewarp $(BUILD)/apps/spacewarp --web-dir $(BUILD)/web/dist \
	  --modules web/node_modules $(if $(SIZES),--sizes $(SIZES))

# Runs each fuzzer (the OBJ, OFF and PLY readers, the rig reader, the VDB input, warp archives) for FUZZ_SECONDS (default 60).
fuzz: deps
	./tests/fuzz/run.sh

format:
	clang-format -i $$(git ls-files '*.h' '*.cpp' 'web/*.js' 'web/*.mjs' 'tests/web/*.mjs' 'bench/*.mjs')

clean:
	rm -rf $(BUILD) $(ASAN_BUILD) build-fuzz out
