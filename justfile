# Everyday recipes. `just --list` shows them.

python := env_var_or_default("PYTHON", "python")

# Record and analyze every experiment of the lab (the README's main command).
lab out="lab-output":
    {{python}} -m impactlab lab -o {{out}}

# Run the test suite (what CI runs).
test *args:
    {{python}} -m pytest {{args}}

# Lint and format check.
lint:
    {{python}} -m ruff check .
    {{python}} -m ruff format --check .

# Regenerate the Python bindings from schemas/*.proto.
schemas:
    {{python}} -m impactlab.proto.generate

# Refresh the lock file from pyproject.toml.
lock:
    {{python}} -m piptools compile --quiet --strip-extras --all-extras --output-file requirements.lock pyproject.toml
