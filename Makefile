# assign5: FastSLAM for ROS 1. `make demo` and `make test` work on a fresh Debian 12.
SHELL := /bin/bash
# Debian's ROS runs on /usr/bin/python3: put the project venv and /usr/bin before any pyenv.
export PATH := $(CURDIR)/.venv/bin:/usr/bin:/bin:$(PATH)
PY := $(CURDIR)/.venv/bin/python
# The catkin workspace of `make setup` lies outside the package folder (see scripts/ws.sh).
WS := $(shell bash scripts/ws.sh)
SETUP_STAMP := $(WS)/.built

.PHONY: setup test test-unit test-ros demo bench screenshot clean
.DEFAULT_GOAL := help

help:
	@echo "make setup       install Debian ROS packages, .venv and build a catkin workspace ($(WS))"
	@echo "make demo        headless SLAM run on the built-in simulator, results in out/demo/"
	@echo "make test        every test (pytest + rostest), ends with 'N passed, M failed'"
	@echo "make bench [SUITE...]  speed, memory and accuracy benchmarks (see docs/benchmarks.md)"
	@echo "make screenshot  RViz under xvfb during a simulator run -> docs/rviz.png"

setup:
	@bash scripts/setup.sh

$(SETUP_STAMP): CMakeLists.txt package.xml setup.py scripts/setup.sh scripts/ws.sh scripts/debian-packages.txt scripts/requirements-dev.txt scripts/requirements-py38.txt $(wildcard src/*.py)
	@bash scripts/setup.sh

test: $(SETUP_STAMP)
	@bash scripts/run-tests.sh all

test-unit: $(SETUP_STAMP)
	@bash scripts/run-tests.sh pytest

test-ros: $(SETUP_STAMP)
	@bash scripts/run-tests.sh rostest

demo: $(SETUP_STAMP)
	@bash scripts/demo.sh

# `make bench speed accuracy`: the words after "bench" name the suites (default: all).
ifeq (bench,$(firstword $(MAKECMDGOALS)))
  SUITES := $(wordlist 2,$(words $(MAKECMDGOALS)),$(MAKECMDGOALS))
  $(eval $(SUITES):;@:)
endif

bench: $(SETUP_STAMP)
	@cd $(CURDIR) && PYTHONPATH=src:. $(PY) -m bench $(SUITES)

screenshot: $(SETUP_STAMP)
	@bash scripts/screenshot.sh

clean:
	rm -rf out "$(WS)"
