# Airlight: the two entry points are `make demo` and `make test` (see README.md).
# Both install the Debian packages they need first (tools/install_deps.sh, as root).

PYTHON   := /usr/bin/python3
BUILD    := build
JOBS     ?= 2
XVFB     := xvfb-run -a -s "-screen 0 1280x1024x24"
BLENDER  := tools/blender.sh

.PHONY: all deps build package demo test test-native test-python test-blender test-gpu test-farm sanitize bench clean

all: build

deps:
	bash tools/install_deps.sh

build: deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DPython_EXECUTABLE=$(PYTHON)
	cmake --build $(BUILD) -j$(JOBS)

# An installable add-on zip (Preferences > Add-ons > Install): the package, its compiled
# module and the GLSL sources (searched in airlight/shaders/ when installed).
# (tools/package.py; tests/blender/test_package.py installs it into a clean Blender.)
package: build
	$(PYTHON) tools/package.py $(BUILD)/airlight.zip

# Builds everything, installs the add-on into an isolated Blender user directory and
# renders the example street headless with fog baked into compositing passes -> out/.
demo: build
	mkdir -p out
	$(BLENDER) -b blend_examples/street.blend --python tools/demo.py -- out

test: build
	$(MAKE) --no-print-directory test-native test-python test-blender test-gpu test-farm

test-native:
	cd $(BUILD) && ctest --output-on-failure -j$(JOBS)

test-python:
	$(PYTHON) -m pytest tests/native -q

test-blender:
	$(BLENDER) -b --python tests/blender/run_tests.py -- -q

test-gpu:
	$(XVFB) $(BLENDER) --python tests/gpu/run_gpu_tests.py -- -q

# Render farms: a single-node Slurm started by the tests, the Flamenco job type through node,
# a worker without the compiled module (needs root, slurm-wlm, munge, nodejs: make deps).
test-farm:
	$(PYTHON) -m pytest tests/farm -q

# The C++ tests and the native pytest under AddressSanitizer and UndefinedBehaviorSanitizer,
# from their own build (build-sanitize/, its module there too): any out-of-bounds access,
# use after free or undefined behaviour reachable from the bindings fails the run.
SANITIZE := build-sanitize
SAN_FLAGS := -fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer
sanitize: deps
	cmake -S . -B $(SANITIZE) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPython_EXECUTABLE=$(PYTHON) \
	  -DCMAKE_CXX_FLAGS="$(SAN_FLAGS)" -DCMAKE_EXE_LINKER_FLAGS="$(SAN_FLAGS)" \
	  -DCMAKE_SHARED_LINKER_FLAGS="$(SAN_FLAGS)" -DCMAKE_INTERPROCEDURAL_OPTIMIZATION=OFF \
	  -DAIRLIGHT_MODULE_DIR=$(CURDIR)/$(SANITIZE)/module
	cmake --build $(SANITIZE) -j$(JOBS)
	cd $(SANITIZE) && ASAN_OPTIONS=detect_leaks=0 UBSAN_OPTIONS=print_stacktrace=1 ctest --output-on-failure -j$(JOBS)
	AIRLIGHT_NATIVE_DIR=$(CURDIR)/$(SANITIZE)/module ASAN_OPTIONS=detect_leaks=0 \
	  UBSAN_OPTIONS=print_stacktrace=1 LD_PRELOAD="$$(g++ -print-file-name=libasan.so) $$(g++ -print-file-name=libubsan.so)" \
	  $(PYTHON) -m pytest tests/native -q -x

bench: build
	$(PYTHON) benchmarks/bench_sun05.py

clean:
	rm -rf $(BUILD) $(SANITIZE) out addon/airlight/_native*.so
