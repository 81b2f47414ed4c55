# pppbot: the README's two commands are `make run` and `make test`.
# Each sets the environment up on first use (./pppbot does it).

PYTEST_ARGS ?=
# Test files run in parallel, one worker per core, the files marked heavy first (tests/conftest.py);
# a file's tests stay on one worker (they share its fixtures). PYTEST_WORKERS=0: all in one process.
PYTEST_WORKERS ?= auto

.PHONY: setup run test check lock clean

setup:
	./pppbot setup

run:
	./pppbot launch_sim

# The tests also run the optional Ray extra (pppbot eval batch --ray on a local instance).
test: check
	./pppbot setup --quiet --ray
	./pppbot env python -m pytest -n $(PYTEST_WORKERS) --dist loadfile --no-loadscope-reorder $(PYTEST_ARGS)

# Static checks: lint (ruff, rules in pyproject.toml) and types (mypy) across packages, tools and tests.
check:
	./pppbot env ruff check --quiet pppbot_common pppbot_lockstep pppbot_description pppbot_sim \
		pppbot_control pppbot_slam pppbot_nav pppbot_bag pppbot_bringup pppbot_eval pppbot_viz tools tests benchmarks \
		examples
	./pppbot env python -m mypy

# Regenerate requirements.txt (the pinned lock) from requirements.in.
lock:
	rm -rf build/lock-venv
	python3 -m venv build/lock-venv
	build/lock-venv/bin/pip install --disable-pip-version-check -q -r requirements.in
	build/lock-venv/bin/python tools/freeze_lock.py > requirements.txt
	rm -rf build/lock-venv

clean:
	rm -rf build install log .venv
