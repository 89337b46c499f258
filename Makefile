# fwemu — every target installs what it needs (a .venv made here; Debian tools via apt when run as root).
#   make main   golden vectors + budget report + apogee table (out/evaluate/) for the default firmware builds
#   make test   the whole test suite (what CI runs)
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
FWEMU := $(VENV)/bin/fwemu
STAMP := $(VENV)/.installed
# Debian packages the tests use: GNU as for the encoding oracle; cross toolchains + simulators for the MCU runs.
# The ARM ones go in without recommends (the recommended libstdc++ for arm-none-eabi is 1.5 GB).
APT_TOOLS := binutils-m68k-linux-gnu gcc-avr avr-libc simavr
APT_PROBE := m68k-linux-gnu-as avr-gcc simavr
APT_ARM := gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm
APT_ARM_PROBE := arm-none-eabi-gcc qemu-system-arm

.PHONY: all venv tools test test-mcu test-thorough vectors budget evaluate main bench clean

all: main

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test,plot,flights,fast]'
	touch $(STAMP)

venv: $(STAMP)

# Install the Debian tools when missing and we are root (CI, fresh machines); otherwise the tests that need them skip.
tools:
	@missing=""; for t in $(APT_PROBE); do command -v $$t >/dev/null 2>&1 || missing="$$missing $$t"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing Debian tools ($(APT_TOOLS)) for:$$missing"; \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(APT_TOOLS) >/dev/null) \
	      || echo "warning: apt-get install failed; tests needing$$missing will skip"; \
	  else echo "note:$$missing not installed (not root): tests needing it will skip"; fi; \
	fi
	@missing=""; for t in $(APT_ARM_PROBE); do command -v $$t >/dev/null 2>&1 || missing="$$missing $$t"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    echo "installing Debian tools ($(APT_ARM)) for:$$missing"; \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
	      $(APT_ARM) >/dev/null) || echo "warning: apt-get install failed; tests needing$$missing will skip"; \
	  else echo "note:$$missing not installed (not root): tests needing it will skip"; fi; \
	fi

# The golden vectors on Cortex-M0/M3/M4 (qemu-system-arm) at -Os and -O2: one closing line per core and level.
# The same runs are tests in tests/vectors/test_c_port_mcu.py, so `make test` does not run them twice: pytest prints the
# six closing lines in its "closing lines" section (tests/conftest.py). This target runs them alone.
test-mcu: tools
	@if command -v arm-none-eabi-gcc >/dev/null 2>&1 && command -v qemu-system-arm >/dev/null 2>&1; then \
	  $(MAKE) -s -C vectors/c cortex-m BUILD=$(abspath build/mcu); \
	else echo "test-mcu: arm-none-eabi-gcc / qemu-system-arm not installed: Cortex-M runs skipped"; fi

test: $(STAMP) tools
	$(PY) -m pytest -q -n 2 --dist worksteal -p no:cacheprovider

test-thorough: $(STAMP) tools
	HYPOTHESIS_PROFILE=thorough $(PY) -m pytest -q -n 2 --dist worksteal -p no:cacheprovider

vectors: $(STAMP)
	$(FWEMU) vectors --all --jobs 2 --out vectors

budget: $(STAMP)
	$(FWEMU) budget --out out/budget

# The apogee table of the default builds over the evaluation set (simulated scenarios + ../shared/flights logs).
evaluate: $(STAMP)
	$(FWEMU) evaluate set:eval --jobs 2 --out out/evaluate

main: vectors budget evaluate

bench: $(STAMP)
	$(PY) -m bench.bench_cpu
	$(PY) -m bench.bench_model
	$(PY) -m bench.bench_sim1dof

clean:
	rm -rf $(VENV) build *.egg-info out
