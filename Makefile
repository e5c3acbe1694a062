# fuzzystereo — top-level entry points (Debian 12). CMake does the real work; see CMakePresets.json.
#
#   make deps           install missing apt packages (sudo when not root) and the host venv
#   make build          native Release build            (preset: default -> build/default)
#   make build-aarch64  cross build of the libraries, unit tests and the program (preset: aarch64 ->
#                       build/aarch64; the program's arm64 libraries unpacked in build/arm64-debs)
#   make test           deps, native build + ctest, pytest (tests/python), aarch64 build + ctest
#                       under qemu and the aarch64 program's outputs compared with the native ones,
#                       the core tests on a non-AVX2 x86-64 CPU (qemu -cpu Nehalem);
#                       runs every stage and exits non-zero if any failed
#   make test-asan      native Debug build with ASan/UBSan + ctest (preset: asan)
#   make demo           deps, build, then the closed-loop simulator run -> out/demo/report.html
#   make demo-match     the matcher alone on the OpenCV "aloe" pair -> out/demo-match
#   make targets        deps, build, then every issue target measured -> out/targets/index.html
#                       (~10 min on two cores; TARGETS_ARGS="--quick" for a 40 s check of the chain)
#   make install        install fuzzystereo and the default configs under PREFIX (/usr/local)
#   make clean          remove build/ and out/   (make distclean also removes .venv)

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
MAKEFLAGS += --no-print-directory
.DEFAULT_GOAL := build

NPROC := $(shell nproc 2>/dev/null || echo 2)

# Stereo datasets for quality tests; tests skip with a message when the directory is absent.
FUZZYSTEREO_DATASETS ?= $(abspath $(CURDIR)/../shared/datasets)
export FUZZYSTEREO_DATASETS

# ---- dependencies --------------------------------------------------------------------------------
# The host's Debian architecture: amd64 on a build machine, arm64 on the robot itself (Raspberry Pi
# OS bookworm). On an arm64 host the aarch64 build is the native one: no cross compiler (Debian has
# no g++-aarch64-linux-gnu for arm64) and no qemu; the `:arm64` packages are then native ones.
HOST_ARCH := $(shell dpkg --print-architecture 2>/dev/null || echo unknown)
APT_PACKAGES := build-essential cmake ninja-build pkg-config \
  libopencv-dev opencv-doc libeigen3-dev libtomlplusplus-dev libcli11-dev nlohmann-json3-dev \
  libgtest-dev googletest libbenchmark-dev libgpiod-dev libcamera-dev \
  python3-venv python3-dev \
  libgtest-dev:arm64 libtomlplusplus-dev:arm64 libgpiod-dev:arm64
ifneq ($(HOST_ARCH),arm64)
APT_PACKAGES += g++-aarch64-linux-gnu qemu-user
endif
SUDO := $(if $(filter 0,$(shell id -u)),,sudo)

PYTHON3 ?= python3
VENV := .venv
VENV_PY := $(VENV)/bin/python
# Touched after `pip install -e host[test]`; re-install only when host/pyproject.toml is newer.
VENV_STAMP := $(VENV)/.fuzzystereo-host-installed
PYPROJECT := $(wildcard host/pyproject.toml)

.PHONY: deps deps-apt deps-python
deps: deps-apt deps-python

deps-apt:
	@missing=""; native=$$(dpkg --print-architecture); \
	for p in $(APT_PACKAGES); do \
	  case "$$p" in *:*) name="$${p%%:*}"; archs="$${p#*:}";; *) name="$$p"; archs="$$native|all";; esac; \
	  status=$$(dpkg-query -W -f='$${Status} $${Architecture}\n' "$$name" 2>/dev/null || true); \
	  grep -qE "^install ok installed ($$archs)$$" <<<"$$status" || missing="$$missing $$p"; \
	done; \
	if [ -z "$$missing" ]; then echo "deps: all apt packages present"; exit 0; fi; \
	echo "deps: installing:$$missing"; \
	foreign=" $$(dpkg --print-foreign-architectures | tr '\n' ' ') "; \
	if [[ "$$native" != arm64 && "$$missing" == *:arm64* && "$$foreign" != *" arm64 "* ]]; then \
	  $(SUDO) dpkg --add-architecture arm64; \
	fi; \
	$(SUDO) apt-get update; \
	$(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends $$missing

deps-python: $(if $(PYPROJECT),$(VENV_STAMP),$(VENV_PY))

$(VENV_PY): | deps-apt
	$(PYTHON3) -m venv $(VENV)

$(VENV_STAMP): $(PYPROJECT) | $(VENV_PY)
	$(VENV_PY) -m pip install --disable-pip-version-check -e 'host[test]'
	touch $@

# ---- build ---------------------------------------------------------------------------------------
.PHONY: build build-aarch64 build-asan
build:
	cmake --preset default
	cmake --build --preset default -j $(NPROC)

# The aarch64 build covers the program too: cmake/arm64-debs.sh unpacks the arm64 OpenCV, libcamera and
# libgpiod (and what they load) into $(ARM64_DEBS) — Debian's arm64 OpenCV cannot be installed beside the
# amd64 one — and the preset links against them (cmake/opencv-debs, the toolchain's FS_ARM64_DEBS). If the
# download fails, the libraries and their unit tests are built alone, as before, and the stage says so.
ARM64_DEBS := $(CURDIR)/build/arm64-debs
build-aarch64:
	@app=OFF; \
	if [ "$(HOST_ARCH)" != arm64 ]; then \
	  if cmake/arm64-debs.sh $(ARM64_DEBS); then app=ON; \
	  else echo "build-aarch64: WARNING: the program's arm64 libraries could not be fetched; building the libraries and their unit tests only"; fi; \
	fi; \
	if [ $$app = ON ]; then \
	  PKG_CONFIG_LIBDIR=$(ARM64_DEBS)/usr/lib/aarch64-linux-gnu/pkgconfig:$(ARM64_DEBS)/usr/share/pkgconfig \
	  PKG_CONFIG_SYSROOT_DIR=$(ARM64_DEBS) \
	  cmake --preset aarch64 -DFS_BUILD_APP=ON -DFS_ARM64_DEBS=$(ARM64_DEBS) -DOpenCV_DIR=$(CURDIR)/cmake/opencv-debs; \
	else \
	  rm -f build/aarch64/fuzzystereo; cmake --preset aarch64 -DFS_BUILD_APP=OFF; \
	fi
	cmake --build --preset aarch64 -j $(NPROC)

build-asan:
	cmake --preset asan
	cmake --build --preset asan -j $(NPROC)

# ---- tests ---------------------------------------------------------------------------------------
.PHONY: test test-native test-python test-aarch64 test-x86-baseline test-asan test-asan-core
# Every stage runs even after a failure, so one CI run reports everything; the exit code is
# non-zero if any stage failed.
test: deps
	@failed=""; \
	for stage in test-native test-python test-aarch64 test-x86-baseline test-asan-core; do \
	  echo "==== $$stage"; \
	  $(MAKE) $$stage || failed="$$failed $$stage"; \
	done; \
	if [ -n "$$failed" ]; then echo "==== FAILED:$$failed"; exit 1; fi; \
	echo "==== all test stages passed"

test-native: build
	ctest --preset default -j $(NPROC)

# The venv's python, so the suite uses exactly the host package installed by `make deps`.
test-python:
	@if ! ls tests/python/test_*.py >/dev/null 2>&1; then echo "no tests in tests/python"; exit 0; fi; \
	if [ ! -x $(VENV_PY) ]; then echo "$(VENV_PY) missing: run 'make deps'"; exit 1; fi; \
	$(VENV_PY) -m pytest tests/python -q -rs

# Unit tests cross-compiled for aarch64, run under qemu-aarch64 (CMAKE_CROSSCOMPILING_EMULATOR).
# On an arm64 host (the robot) test-native has already run every unit test on aarch64.
ifeq ($(HOST_ARCH),arm64)
test-aarch64:
	@echo "test-aarch64: this host is arm64; test-native ran the unit tests on aarch64 natively"
else
test-aarch64: build-aarch64 build deps-python
	ctest --preset aarch64 -j $(NPROC)
	@if [ -x build/aarch64/fuzzystereo ]; then \
	  $(VENV_PY) tests/aarch64/compare_program.py --native build/default/fuzzystereo \
	    --arm64 "build/aarch64/run-target build/aarch64/fuzzystereo" --work build/aarch64/compare; \
	else echo "test-aarch64: the aarch64 program was not built (see build-aarch64); its comparison is skipped"; fi
endif

# The x86-64 baseline: the core and simulator unit tests (the golden pipeline hashes among them) under
# `qemu-x86_64 -cpu Nehalem`, a CPU without AVX/AVX2. The kernels' target_clones "default" branches and
# the run-time fallbacks (ESR's sliding kernel, the boundary stage's SWAR bit count) run there, which
# a build machine with AVX2 never executes natively. Only on amd64 hosts with qemu-user.
QEMU_X86 := $(shell command -v qemu-x86_64 2>/dev/null)
test-x86-baseline: build
	@if [ "$(HOST_ARCH)" != amd64 ] || [ -z "$(QEMU_X86)" ]; then \
	  echo "test-x86-baseline: needs an amd64 host with qemu-x86_64 (apt package qemu-user); skipped"; exit 0; fi; \
	for t in fs_core_tests fs_sim_tests; do \
	  echo "qemu-x86_64 -cpu Nehalem build/default/tests/cpp/$$t"; \
	  $(QEMU_X86) -cpu Nehalem build/default/tests/cpp/$$t --gtest_brief=1; \
	done

test-asan: deps build-asan
	ctest --preset asan -j $(NPROC)

# Under AddressSanitizer + UBSan (part of `make test`; the full asan preset is `make test-asan`):
# the core unit tests, the link unit tests and 200k iterations of the link decoder fuzz driver.
test-asan-core:
	cmake --preset asan
	cmake --build --preset asan -j $(NPROC) --target fs_core_tests fs_link_tests fs_link_fuzz
	build/asan/tests/cpp/fs_core_tests
	build/asan/tests/cpp/fs_link_tests
	build/asan/tests/cpp/fs_link_fuzz 200000 11

# ---- demo ----------------------------------------------------------------------------------------
# The closed-loop run: the robot drives common/sim/scenes/demo.toml in the simulator from start to
# goal; out/demo/report.html shows the trajectory, annotated frames and stage timings.
DEMO_OUT := out/demo
DEMO_SCENE ?= common/sim/scenes/demo.toml

.PHONY: demo demo-match
demo: deps build
	@rm -rf $(DEMO_OUT)/run; mkdir -p $(DEMO_OUT); set -x; \
	build/default/fuzzystereo run --source sim:$(DEMO_SCENE) --motors sim --record $(DEMO_OUT)/run \
	  --snapshot-every 5 --quiet --json $(DEMO_OUT)/result.json; \
	$(VENV)/bin/fuzzyctl report $(DEMO_OUT)/run --out $(DEMO_OUT)/report.html

# The matcher alone on OpenCV's sample pair (opencv-doc). Debian may ship some of these files
# gzipped: those are unpacked to out/demo-match/input first.
DEMO_DATA ?= /usr/share/doc/opencv-doc/examples/data
DEMO_MATCH_OUT := out/demo-match

demo-match: deps build
	@mkdir -p $(DEMO_MATCH_OUT); \
	demo_file() { \
	  if [ -f "$(DEMO_DATA)/$$1" ]; then echo "$(DEMO_DATA)/$$1"; \
	  elif [ -f "$(DEMO_DATA)/$$1.gz" ]; then \
	    mkdir -p $(DEMO_MATCH_OUT)/input; gunzip -c "$(DEMO_DATA)/$$1.gz" > "$(DEMO_MATCH_OUT)/input/$$1"; \
	    echo "$(DEMO_MATCH_OUT)/input/$$1"; \
	  else echo "demo: $(DEMO_DATA)/$$1 not found (apt package opencv-doc)" >&2; exit 1; fi; \
	}; \
	left=$$(demo_file aloeL.jpg); right=$$(demo_file aloeR.jpg); gt=$$(demo_file aloeGT.png); \
	set -x; \
	build/default/fuzzystereo match --left "$$left" --right "$$right" --gt "$$gt" \
	  --downscale 3 --max-disparity 80 --out $(DEMO_MATCH_OUT) --dump

# ---- every issue target, measured (fuzzyctl targets) ------------------------------------------------
# eval (clean + radiometric), bench, detect-eval on fresh generated frames, the closed-loop suite, the
# watchdog stall and track-eval, with the bad-input checks: one table and out/targets/index.html.
TARGETS_ARGS ?=
.PHONY: targets
targets: deps build
	$(VENV)/bin/fuzzyctl targets --bin build/default/fuzzystereo --datasets "$(FUZZYSTEREO_DATASETS)" \
	  --out out/targets $(TARGETS_ARGS)

# ---- install (on the robot) -----------------------------------------------------------------------
# The program and the default config files: PREFIX/bin/fuzzystereo, PREFIX/share/fuzzystereo/
# (config/, fis/, sim/scenes/). The binary embeds its default config, so only your own config file
# (e.g. /etc/fuzzystereo/robot.toml, docs/robot.md "systemd unit") is needed at run time.
PREFIX ?= /usr/local
.PHONY: install
install: build
	$(if $(filter 0,$(shell id -u)),,sudo) cmake --install build/default --prefix $(PREFIX)

# ---- housekeeping --------------------------------------------------------------------------------
.PHONY: clean distclean
clean:
	rm -rf build out

distclean: clean
	rm -rf $(VENV)
