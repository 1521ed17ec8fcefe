# SSS Lab: `make demo` runs the main job on the sample scene, `make test` runs lint and tests.
# Each target sets up .venv by itself (tools/bootstrap.sh) on a fresh machine.
# BLENDER=4.5 picks Blender 4.5 LTS (.venv-4.5, Python 3.11, bpy 4.5) instead of 5.2 (.venv);
# `make test` without it tests both versions, as CI does.
BLENDER ?=
ifneq ($(filter-out 5.2 4.5,$(BLENDER)),)
$(error BLENDER=$(BLENDER): expected 5.2 or 4.5 (or nothing: make test then tests both))
endif
venv_of = $(if $(filter 4.5,$(1)),.venv-4.5,.venv)
PY := $(call venv_of,$(BLENDER))/bin/python
TEST_VERSIONS := $(or $(BLENDER),5.2 4.5)
OUT ?= out

.PHONY: venv demo farm-demo test lint typecheck format bench fidelity extension clean

venv:
	@bash tools/bootstrap.sh $(or $(BLENDER),5.2)

demo: venv
	$(PY) -m sss_lab demo --out $(OUT)

# The farm job (farm/openjd/template.yaml) run on this machine by openjd, on the demo scene at a small
# size: passes and .sss.exr per frame, the reference in seed parts, merged, and the comparison report.
# Run it again and every task keeps what exists (--skip-existing) and says so.
FARM_OUT ?= $(OUT)/farm
FARM_PARAMS ?= -p Frames=1-3 -p FramesPerTask=2 -p Resolution=64x64 -p PassSamples=16 \
	-p Compare=yes -p ReferenceTasks=4 -p ReferenceSamples=16

farm-demo: venv
	@[ -f $(FARM_OUT)/head_frontlit.blend ] || $(PY) sample_blends/build_scenes.py head_frontlit --out $(FARM_OUT)
	$(dir $(PY))openjd run farm/openjd/template.yaml --step Compare --run-dependencies \
		-p SceneFile=$(abspath $(FARM_OUT))/head_frontlit.blend -p OutputDir=$(abspath $(FARM_OUT))/job \
		-p "SSSLab=$(abspath $(PY)) -m sss_lab" -p "SSSLabNumpy=$(abspath $(PY)) -m sss_lab" $(FARM_PARAMS)

# Lint and type-check once (mypy in the 5.2 environment), then the whole suite in each version's
# environment; every version runs even when an earlier one fails, and the target fails if any did.
# Each version's kernels are compiled first, two processes side by side (`prepare --jobs 2`): the
# tests would compile them one after another on first use. The later versions' kernels compile in
# the background at low priority while the first version's tests run (they leave part of the two
# cores idle); each version's own prepare then loads them, and compiles what is left.
test: venv
	$(PY) -m ruff check .
	$(PY) -m ruff format --check .
	$(if $(filter 5.2,$(TEST_VERSIONS)),$(PY) tools/typecheck.py,@echo "make test: mypy runs in the Blender 5.2 environment only (the annotations use NumPy 2's stubs; 4.5 has NumPy 1.26)")
	@bash tools/ensure_chromium.sh
	@failed=; for v in $(TEST_VERSIONS); do \
	  bash tools/bootstrap.sh $$v || failed="$$failed $$v"; \
	done; \
	for v in $(wordlist 2,9,$(TEST_VERSIONS)); do \
	  case " $$failed " in *" $$v "*) continue;; esac; \
	  venv=.venv; [ "$$v" = 4.5 ] && venv=.venv-4.5; \
	  nice -n 15 $$venv/bin/python -m sss_lab prepare --quiet >/dev/null 2>&1 & \
	done; \
	for v in $(TEST_VERSIONS); do \
	  case " $$failed " in *" $$v "*) continue;; esac; \
	  venv=.venv; [ "$$v" = 4.5 ] && venv=.venv-4.5; \
	  [ "$$v" = "$(firstword $(TEST_VERSIONS))" ] || wait; \
	  echo "make test: Blender $$v ($$venv)"; \
	  $$venv/bin/python -m sss_lab prepare --jobs 2 --quiet || failed="$$failed $$v"; \
	  $$venv/bin/python -m pytest tests || failed="$$failed $$v"; \
	done; \
	if [ -n "$$failed" ]; then echo "make test: failed on Blender$$failed"; exit 1; fi

lint: venv
	$(PY) -m ruff check .
	$(PY) -m ruff format --check .

# mypy: default checks over core, blender, operators, nodes and addon, strict ones over the core
# modules listed in pyproject.toml ([tool.mypy]).
typecheck: venv
	$(PY) tools/typecheck.py

format: venv
	$(PY) -m ruff format .
	$(PY) -m ruff check --fix .

bench: venv
	$(PY) -m benchmarks.speed
	$(PY) -m benchmarks.input_aovs

# Every technique on every scene of the fidelity suite against the stored Cycles references
# (benchmarks/fidelity/): benchmarks/results/fidelity.json, docs/fidelity.md, docs/images/fidelity_grid.png;
# then the textured pairs (benchmarks/fidelity/textured.py) and their table in docs/fidelity.md, beside the
# stored run of the version before linked inputs were read per pixel and the stored calibrate run.
TEXTURED := --scenes-module benchmarks.fidelity.textured --store benchmarks/fidelity/textured_references
fidelity: venv
	nice -n 10 $(PY) -m benchmarks.fidelity.run
	nice -n 10 $(PY) -m benchmarks.fidelity.run $(TEXTURED) --out benchmarks/results/fidelity_textured.json \
		--table docs/fidelity_textured.md --grid docs/images/fidelity_textured.png
	$(PY) -m benchmarks.fidelity.pairs --twins benchmarks.fidelity.textured \
		--run before=benchmarks/results/fidelity_textured_before.json --run after=benchmarks/results/fidelity_textured.json \
		--run "after, calibrated=benchmarks/results/fit_textured.json" --into docs/fidelity.md

extension: venv
	$(PY) tools/build_extension.py

clean:
	rm -rf dist wheels $(OUT)
