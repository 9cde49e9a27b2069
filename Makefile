# Thin wrapper: every target calls the CLI (python -m codegen ...). The first run creates .venv.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python

.PHONY: generate test sanitize c-tools bench clean check

$(VENV)/.installed: pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $@

$(VENV)/.installed-bench: $(VENV)/.installed
	$(PY) -m pip install --quiet -e '.[test,bench]'
	touch $@

generate: $(VENV)/.installed
	$(PY) -m codegen generate

test: $(VENV)/.installed c-tools
	$(PY) -m pytest
	$(PY) -m codegen sanitize

# the C under ASan/UBSan on edge-case CSVs and a libFuzzer campaign (also part of `make test`)
sanitize: $(VENV)/.installed c-tools
	$(PY) -m codegen sanitize

c-tools:
	sh c_harness/install-tools.sh

check: $(VENV)/.installed
	$(PY) -m codegen check

bench: $(VENV)/.installed-bench
	$(PY) -m codegen bench

clean:
	find generated -mindepth 1 -maxdepth 1 ! -name README.md ! -name .gitignore -exec rm -rf {} +
	rm -rf build
