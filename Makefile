# Vigil: `make run` sets everything up and starts the system; `make test` sets up and tests.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(VENV)/bin/pip
STAMP := $(VENV)/.installed
FRONTEND_STAMP := frontend/node_modules/.installed
PYTEST_ARGS ?=
# Python must be free to cache bytecode: with PYTHONDONTWRITEBYTECODE set (some shells and
# containers set it) every pytest run compiles and assertion-rewrites every module again, and
# so does each backend, agent and worker process the tests start (about 4 s of CPU each).
unexport PYTHONDONTWRITEBYTECODE

.PHONY: run test test-python test-sqlite test-postgresql test-frontend test-browser setup \
	frontend chromium lint format bench-detection bench-detection-splits bench-fall-onset \
	bench-floor bench-ingest bench-robot bench-video bench-labelling bench-registry \
	bench-alarm-latency bench-alarm-distribution bench-hospital-group bench-storage-stall bench-storage bench-login-flood bench-nurse-soak \
	bench-demo-hour readme \
	screenshots \
	clean

setup: $(STAMP) frontend

$(STAMP): pyproject.toml
	test -d $(VENV) || $(PYTHON) -m venv $(VENV)
	$(PIP) install --quiet --upgrade pip
	# torch is pinned to 2.13.0 in pyproject: pip takes the CPU wheel on this machine's disk.
	$(PIP) install --quiet -e '.[robot,train,server,dev,mediapipe]'
	touch $@

$(FRONTEND_STAMP): frontend/package.json frontend/package-lock.json
	cd frontend && npm ci --no-audit --no-fund
	touch $@

frontend: $(FRONTEND_STAMP)
	cd frontend && npm run build

chromium:
	@command -v chromium >/dev/null || (apt-get update -qq && apt-get install -y -qq chromium)

run: setup
	$(PY) -m scripts.run_all

# Two runs side by side, one per core: the database tests on SQLite, and on a throwaway
# PostgreSQL database. The tests that do not depend on the database (domain package, training,
# robot agent, browser tests in Chromium) run once, shared out between the two runs through the
# directory VIGIL_TEST_POOL (tests/support/shared_pool.py): each run takes the next test file
# when it is free, so both runs end at about the same time. The PostgreSQL run is pytest on the
# database tests followed by a SQLite run that owns nothing and helps with the shared files.
# The small test models trained on URFD are trained once for both runs (VIGIL_TEST_MODEL_CACHE,
# tests/support/model_cache.py). The second side's output is printed after the first's.
test: $(STAMP) frontend chromium lint
	@echo "== Python tests on SQLite, and on PostgreSQL (throwaway database), side by side; the database-independent and browser tests shared out between them =="
	@second_log=$$(mktemp); pool=$$(mktemp -d); export VIGIL_TEST_MODEL_CACHE=$$(mktemp -d); \
	( VIGIL_TEST_DATABASE=postgresql $(PY) -m pytest -q -p no:cacheprovider -m "not browser" \
		$(PYTEST_ARGS); postgresql_status=$$?; \
	  echo "-- shared tests (SQLite; the rest ran in the SQLite run) --"; \
	  VIGIL_TEST_DATABASE=sqlite VIGIL_TEST_POOL="$$pool" VIGIL_TEST_OWN=none \
		$(PY) -m pytest -q -p no:cacheprovider $(PYTEST_ARGS); shared_status=$$?; \
	  echo "PostgreSQL run exit status $$postgresql_status, shared run exit status $$shared_status"; \
	  test $$postgresql_status -eq 0 && test $$shared_status -eq 0 ) >"$$second_log" 2>&1 & second_pid=$$!; \
	echo "-- SQLite (and shared tests) --"; \
	VIGIL_TEST_DATABASE=sqlite VIGIL_TEST_POOL="$$pool" VIGIL_TEST_OWN=database \
		$(PY) -m pytest -q -p no:cacheprovider $(PYTEST_ARGS); sqlite_status=$$?; \
	wait $$second_pid; second_status=$$?; \
	echo "-- PostgreSQL --"; cat "$$second_log"; rm -rf "$$second_log" "$$pool" "$$VIGIL_TEST_MODEL_CACHE"; \
	echo "SQLite run exit status $$sqlite_status, PostgreSQL + shared run exit status $$second_status"; \
	test $$sqlite_status -eq 0 && test $$second_status -eq 0
	@echo "== Frontend unit tests =="
	cd frontend && npm test

lint: $(STAMP)
	$(VENV)/bin/ruff check vigil backend worker robot_agent tests bench migrations scripts
	$(VENV)/bin/ruff format --check vigil backend worker robot_agent tests bench migrations scripts

format: $(STAMP)
	$(VENV)/bin/ruff check --fix vigil backend worker robot_agent tests bench migrations scripts
	$(VENV)/bin/ruff format vigil backend worker robot_agent tests bench migrations scripts

bench-detection: $(STAMP)
	$(PY) -m bench.detection

bench-detection-splits: $(STAMP)
	$(PY) -m bench.detection_splits

bench-fall-onset: $(STAMP)
	$(PY) -m bench.fall_onset

bench-floor: $(STAMP)
	$(PY) -m bench.floor_measures

bench-ingest: $(STAMP)
	$(PY) -m bench.ingest

bench-login-flood: $(STAMP)
	$(PY) -m bench.login_flood --databases sqlite,postgresql --compare-unbounded

bench-robot: $(STAMP)
	$(PY) -m bench.robot

bench-video: $(STAMP)
	$(PY) -m bench.video_end_to_end

bench-labelling: $(STAMP)
	$(PY) -m bench.labelling

bench-registry: $(STAMP)
	$(PY) -m bench.registry

bench-alarm-latency: $(STAMP) frontend chromium
	$(PY) -m bench.alarm_latency

# 30 minutes in Chromium (VIGIL_SOAK_MINUTES=2 for a quick check); not part of `make test`.
bench-nurse-soak: $(STAMP) frontend chromium
	$(PY) -m bench.nurse_soak

# An hour of make run's system on a throwaway data directory: the board against the simulated
# fall rate, the models the robots run (counts and order, not speed: it runs under nice).
bench-demo-hour: $(STAMP) frontend chromium
	nice -n 10 $(PY) -m bench.demo_hour

bench-storage-stall: $(STAMP)
	$(PY) -m bench.storage_stall

# 100 robots at 10 Hz, a kill -9 of the backend and a 60 s Alert Manager outage (issue 32).
bench-alarm-distribution: $(STAMP)
	$(PY) -m bench.alarm_distribution

# Two replicas, kill -9 of the one running the duties (issue 36); writes ingest.json's hospital_group
bench-hospital-group: $(STAMP)
	$(PY) -m bench.hospital_group --robots 100 --processes 2
	$(PY) -m bench.hospital_group --robots 300 --processes 2
	$(PY) -m bench.hospital_group --robots 1000 --processes 4

# Frames at hospital scale (issue 20); sizes: python -m bench.storage --help
bench-storage: $(STAMP)
	$(PY) -m bench.storage

# The screenshots in docs/ come from the browser tests (a plain test run keeps them in /tmp).
screenshots: $(STAMP) frontend chromium
	VIGIL_SCREENSHOT_DIR=docs/screenshots $(PY) -m pytest -q -m browser tests/browser

# README's configuration and benchmark sections are generated; tests/test_readme.py checks them.
readme: $(STAMP)
	$(PY) -m scripts.readme --write

clean:
	rm -rf var frontend/dist
