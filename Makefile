# Thin wrapper: every target calls the CLI (python -m codegen ...). The first run creates .venv.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python

# the Cortex-M flow (`make embedded`): Debian's cross compiler, its C library, QEMU, and newlib's
# sources (its libm rebuilt for the host: the firmware's math on both sides of the comparison)
ARM_PACKAGES := gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm newlib-source
SUDO := $(if $(filter 0,$(shell id -u)),,sudo)

.PHONY: generate test test-fast test-long test-real sanitize c-tools bench clean check embedded arm-toolchain docs docs-figures

$(VENV)/.installed: pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $@

$(VENV)/.installed-docs: $(VENV)/.installed
	$(PY) -m pip install --quiet -e '.[test,docs]'
	touch $@

$(VENV)/.installed-bench: $(VENV)/.installed
	$(PY) -m pip install --quiet -e '.[test,bench]'
	touch $@

generate: $(VENV)/.installed
	$(PY) -m codegen generate -c targets.toml

# every test but the experiment-scale ones (marked long) and the real logs' (marked real), in
# parallel on every core (pytest-xdist), then the sanitizers and the fuzzer: under 10 minutes on 2 cores
test: $(VENV)/.installed c-tools
	$(PY) -m pytest -n auto -m "not long and not real"
	$(PY) -m codegen sanitize

# the quick set for iteration (no test marked slow or long), under 2 minutes on 2 cores
test-fast: $(VENV)/.installed
	$(PY) -m pytest -n auto -m "not slow and not long and not real"

# the experiment-scale tests (a real arm's identification and observers, the elastic
# cross-checks, xarm7): CI runs them after `make test`
test-long: $(VENV)/.installed
	$(PY) -m pytest -n auto -m "long and not real"

# the real arms' logs (tests/real: $$CODEGEN_REAL_LOGS or ../shared/data/real; skipped with one line
# when neither exists): each arm's clock, identification, velocity and the user's flow judged
# against the robot's own velocity signal (each command run once, its result shared by the workers).
# CI runs it after `make test`
test-real: $(VENV)/.installed c-tools
	$(PY) -m pytest -n auto -m real -rxXs

# the C under ASan/UBSan on edge-case CSVs and a libFuzzer campaign (also part of `make test`)
sanitize: $(VENV)/.installed c-tools
	$(PY) -m codegen sanitize

c-tools:
	sh c_harness/install-tools.sh

check: $(VENV)/.installed
	$(PY) -m codegen check -c targets.toml

embedded: $(VENV)/.installed arm-toolchain
	$(PY) -m codegen embedded -c targets.toml   # every default target: float on a Cortex-M4F, double on a Cortex-M7

# apt-get installs what is missing of $(ARM_PACKAGES)
arm-toolchain:
	@missing=""; \
	command -v arm-none-eabi-gcc >/dev/null || missing="$$missing gcc-arm-none-eabi"; \
	test -f "$$(arm-none-eabi-gcc -print-file-name=libc.a 2>/dev/null)" || missing="$$missing libnewlib-arm-none-eabi"; \
	command -v qemu-system-arm >/dev/null || missing="$$missing qemu-system-arm"; \
	ls /usr/src/newlib/newlib-*.tar.xz >/dev/null 2>&1 || missing="$$missing newlib-source"; \
	if [ -n "$$missing" ]; then \
	  echo "installing$$missing"; \
	  $(SUDO) apt-get update -qq && \
	  $(SUDO) env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; \
	fi

# the documentation site (MkDocs + mkdocstrings, mkdocs.yml) into build/site, strict: any warning (a
# broken internal link or anchor, a page outside the navigation, an unresolved cross-reference)
# fails it. External links are not checked (no network but the package index). Then the built
# site is checked for an anchor per public module, function and class (tests/test_docs_site.py).
docs: $(VENV)/.installed-docs
	NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs build --strict
	DOCS_SITE=build/site $(PY) -m pytest -q -p no:xdist tests/test_docs_site.py -k built_site

# the figures of the observer pages and of docs/papers/reproduced.md, from the runs that make them
docs-figures: $(VENV)/.installed
	sh tools/docs_figures.sh

bench: $(VENV)/.installed-bench
	$(PY) -m codegen bench

clean:
	find generated -mindepth 1 -maxdepth 1 ! -name README.md ! -name .gitignore -exec rm -rf {} +
	rm -rf build
