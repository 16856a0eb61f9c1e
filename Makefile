# The two commands of the README: `make demo` (everything, end to end, on the default scene)
# and `make test` (what CI runs). Both install what is missing first.
CARGO  ?= cargo
BIN    := target/release/cvtrace
SCENE  ?= scenes/cornell-box/scene.gltf
OUT    ?= out/cornell-box
SPP    ?= 32
SEEDS  ?= 4
REF_SPP ?= 4096

.PHONY: setup build demo test bench clean-demo

setup:
	@bash scripts/setup.sh

build: setup
	$(CARGO) build --release --locked

# Renders (or reuses) a reference, renders paired streams, reconstructs with every estimator.
demo: build
	@mkdir -p $(OUT)
	@test -f $(OUT)/reference.exr || $(BIN) render $(SCENE) --reference --spp $(REF_SPP) -o $(OUT)/reference.exr
	$(BIN) render $(SCENE) --spp $(SPP) --batches 16 --seed 7 --force -o $(OUT)/streams.exr
	$(BIN) reconstruct $(OUT)/streams.exr --method all --reference $(OUT)/reference.exr --force -o $(OUT)/recon
	@echo "demo: results in $(OUT)/recon"

test: setup
	$(CARGO) test --workspace --locked

bench: setup
	$(CARGO) bench --workspace

clean-demo:
	rm -rf $(OUT)
