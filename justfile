# Everyday recipes. `just --list` shows them. PYTHON=... picks the interpreter.

python := env_var_or_default("PYTHON", "python")

# Record, analyze and replay every experiment (the README's main command).
lab out="lab-output":
    {{python}} -m impactlab lab -o {{out}}

# Run the fast tier of the tests (everything not marked slow).
test *args:
    {{python}} -m pytest {{args}}

# Run both tiers, the whole suite (what CI runs).
test-all *args:
    {{python}} -m pytest -m "slow or not slow" {{args}}

# Lint, format check and the type check (mypy strict on the whole package, [tool.mypy] in pyproject.toml).
lint:
    {{python}} -m ruff check .
    {{python}} -m ruff format --check .
    {{python}} -m mypy

# Regenerate the Python bindings from schemas/*.proto.
schemas:
    {{python}} -m impactlab.proto.generate

# Regenerate the golden logs of tests/golden/ on purpose (prints what changed); `just golden --check` only reports.
golden *args:
    {{python}} -m impactlab.golden {{args}}

# Benchmarks: recording, decoding, analysis and replay against their baselines.
bench:
    {{python}} benchmarks/bench.py

# Refresh the lock file from pyproject.toml.
lock:
    {{python}} -m piptools compile --quiet --strip-extras --all-extras --output-file requirements.lock pyproject.toml

# Refresh the README's figure from the lab report (docs/report-restitution.png).
readme-figure out="/tmp/impactlab-readme-lab":
    {{python}} -m impactlab lab -o {{out}} --calibration none --no-replay
    cp {{out}}/results/figures/restitution-vs-speed.png docs/report-restitution.png
