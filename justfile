# Everyday recipes. `just --list` shows them. PYTHON=... picks the interpreter (default: the
# README's .venv when there is one). A recipe whose tool is in an extra of pyproject.toml
# installs that extra first, pinned by requirements.lock, when its module is missing.

python := env_var_or_default("PYTHON", if path_exists(".venv/bin/python") == "true" { ".venv/bin/python" } else { "python3" })

# Record, analyze and replay every experiment (the README's main command).
lab out="lab-output":
    {{python}} -m impactlab lab -o {{out}}

# Run the fast tier of the tests (everything not marked slow).
test *args: (needs "pytest" "test")
    {{python}} -m pytest {{args}}

# Run both tiers, the whole suite (the README's test command; .ci/run also runs `-m extras`).
test-all *args: (needs "pytest" "test")
    {{python}} -m pytest -m "slow or not slow" {{args}}

# Lint, format check and the type check (mypy strict on the whole package, [tool.mypy] in pyproject.toml).
lint: (needs "mypy" "test")
    {{python}} -m ruff check .
    {{python}} -m ruff format --check .
    {{python}} -m mypy

# Regenerate the Python bindings from schemas/*.proto.
schemas: (needs "grpc_tools" "schemas")
    {{python}} -m impactlab.proto.generate

# Regenerate the golden logs of tests/golden/ on purpose (prints what changed); `just golden --check` only reports.
golden *args:
    {{python}} -m impactlab.golden {{args}}

# Benchmarks: recording, decoding, analysis and replay against their baselines (`just bench --quick`: a short run).
bench *args:
    {{python}} benchmarks/bench.py {{args}}

# Refresh the lock file from pyproject.toml (every extra; no index or find-links of this machine).
lock: (needs "piptools" "dev")
    CUSTOM_COMPILE_COMMAND="just lock" {{python}} -m piptools compile --quiet --strip-extras --all-extras --no-emit-index-url --no-emit-find-links --output-file requirements.lock pyproject.toml

# Refresh the README's figure from the lab report (docs/report-restitution.png).
readme-figure out="/tmp/impactlab-readme-lab":
    {{python}} -m impactlab lab -o {{out}} --no-replay
    cp {{out}}/results/figures/restitution-vs-speed.png docs/report-restitution.png

# Install an extra of pyproject.toml (pinned by the lock) when its module is missing.
[private]
needs module extra:
    @{{python}} -c "import {{module}}" 2>/dev/null || {{python}} -m pip install --quiet -c requirements.lock -e ".[{{extra}}]"
