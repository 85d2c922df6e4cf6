"""Experiment specs: TOML over the schema's defaults, set by dotted path, validated (`RunSpec`)."""

from __future__ import annotations

import difflib
import hashlib
import json
import tomllib
import types
import typing
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from pydantic import ValidationError

from impactlab.errors import SpecError
from impactlab.files import read_regular
from impactlab.logs.geoms import BODY_PALETTE
from impactlab.record.schema import (
    SECTIONS,
    Body,
    BodySpec,
    Contact,
    Options,
    Plane,
    Section,
    SpecDocument,
    Stop,
    defaults,
    short,
)

__all__ = ["Body", "Contact", "Options", "Plane", "RunSpec", "Stop"]

SPEC_TOP_KEYS = (*SpecDocument.model_fields, "sweep")
MAX_SPEC_BYTES = 10_000_000  # a spec file larger than this is not a spec


@dataclass(frozen=True)
class RunSpec:
    """One fully resolved run: the experiment's spec with overrides and one sweep point applied."""

    experiment: str
    description: str
    source: str
    options: Options
    contact: Contact
    plane: Plane
    bodies: tuple[Body, ...]
    stop: Stop
    log_every: int
    sweep_values: Mapping[str, Any]
    document: Mapping[str, Any]
    sweep_index: int = 0  # this run's place in its sweep grid
    sweep_size: int = 1  # runs in the grid

    @property
    def spec_hash(self) -> str:
        """SHA-256 (hex) of the resolved document: equal hashes mean identical runs."""
        return spec_hash(self.document)


def spec_hash(document: Mapping[str, Any]) -> str:
    """SHA-256 (hex) of a resolved spec document in canonical JSON."""
    canonical = json.dumps(document, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def read_toml(path: Path) -> dict[str, Any]:
    """Read a TOML file, turning I/O and syntax errors into `SpecError`."""
    try:
        text = read_regular(path, MAX_SPEC_BYTES).decode("utf-8")
    except FileNotFoundError:
        raise SpecError(str(path), "", "file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(str(path), "", f"cannot read: {exc}") from None
    return parse_toml(text, str(path))


def parse_toml(text: str, source: str, field: str = "") -> dict[str, Any]:
    """Parse TOML text; syntax errors and absurd nesting become `SpecError`."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(source, field, f"invalid TOML: {exc}") from None
    except RecursionError:
        raise SpecError(source, field, "invalid TOML: nested too deeply") from None


def merge_defaults(raw: Mapping[str, Any], source: str) -> dict[str, Any]:
    """The spec document with every omitted value filled from the schema's defaults.

    Unknown keys and sections that are not tables fail here; values are checked by
    `validate` once overrides and the sweep point are applied.
    """
    unknown = sorted(set(raw) - set(SPEC_TOP_KEYS), key=str)
    if unknown:
        raise SpecError(source, unknown[0], unknown_key(unknown[0], SPEC_TOP_KEYS))
    doc: dict[str, Any] = {"name": raw.get("name", Path(source).stem)}
    doc["description"] = raw.get("description", "")
    for section, schema in SECTIONS.items():
        doc[section] = _filled(raw.get(section, {}), schema, section, source)
    bodies = raw.get("bodies")
    if not isinstance(bodies, Mapping) or not bodies:
        raise SpecError(source, "bodies", "at least one body is required ([bodies.NAME] tables)")
    doc["bodies"] = {
        name: _filled(body, BodySpec, f"bodies.{name}", source) for name, body in bodies.items()
    }
    return doc


def _filled(given: Any, schema: type[Section], field: str, source: str) -> dict[str, Any]:
    """A table of the spec over its schema's defaults; not a table, or an unknown key, fails."""
    if not isinstance(given, Mapping):
        raise SpecError(source, field, f"must be a table, got {short(given)}")
    unknown = sorted(set(given) - set(schema.model_fields), key=str)
    if unknown:
        raise SpecError(
            source, f"{field}.{unknown[0]}", unknown_key(unknown[0], schema.model_fields)
        )
    return {**defaults(schema), **plain_copy(given)}


def unknown_key(key: object, known: Iterable[str]) -> str:
    """The problem of a key that is not in `known`: the closest known one, and all of them."""
    return f"unknown key{did_you_mean(str(key), known)} (known: {', '.join(known)})"


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """`, did you mean 'x'?` for the known name closest to a misspelt one, or ''."""
    close = difflib.get_close_matches(name, list(known), n=1)
    return f", did you mean {close[0]!r}?" if close else ""


def value_fields(doc: Mapping[str, Any], schema: type[Section] = SpecDocument) -> dict[str, Any]:
    """Every value of `doc` (a document of `schema`) a `--set` or `[sweep]` key can name: its
    resolved dotted path (`bodies.ball.mass`) -> its type."""

    def walk(section: type[Section], prefix: str) -> Iterable[tuple[str, Any]]:
        for name, info in section.model_fields.items():
            annotation = info.annotation
            if section is SpecDocument and name == "bodies":
                for body in doc.get("bodies", {}):
                    yield from walk(BodySpec, f"bodies.{body}.")
            elif isinstance(annotation, type) and issubclass(annotation, Section):
                yield from walk(annotation, f"{prefix}{name}.")
            else:
                yield f"{prefix}{name}", annotation

    return dict(walk(schema, ""))


def check_path(
    doc: Mapping[str, Any], path: str, source: str, schema: type[Section] = SpecDocument
) -> tuple[list[str], Any]:
    """The resolved keys of a dotted path that names a value of `doc` (of `schema`), and its
    type (`ball.mass` resolves to `bodies.ball.mass`).

    Raises:
        SpecError: the path names nothing, or a table (set its fields instead).
    """
    keys = path.split(".")
    if keys[0] not in doc and keys[0] in doc.get("bodies", {}):  # `ball.mass`: a body's
        keys = ["bodies", *keys]
    bodies = list(doc.get("bodies", {}))
    if keys[0] == "bodies" and len(keys) > 1 and keys[1] not in bodies:
        hint = did_you_mean(keys[1], bodies)
        raise SpecError(
            source, path, f"unknown body {keys[1]!r}{hint} (known: {', '.join(bodies)})"
        )
    fields, full = value_fields(doc, schema), ".".join(keys)
    if full in fields:
        return keys, fields[full]
    inside = [p.removeprefix(f"{full}.").split(".")[0] for p in fields if p.startswith(f"{full}.")]
    if not inside:
        hint = did_you_mean(path, [p.removeprefix("bodies.") for p in fields])
        raise SpecError(source, path, f"unknown field {full!r}{hint}")
    names = ["bodies.NAME.FIELD"] if keys == ["bodies"] else list(dict.fromkeys(inside))
    example = "mass" if keys == ["bodies"] else names[0]
    raise SpecError(
        source,
        path,
        f"is a table; set its fields instead, e.g. {full}.{example}=... "
        f"(fields: {', '.join(names)})",
    )


def set_path(
    doc: dict[str, Any], path: str, value: Any, source: str, schema: type[Section] = SpecDocument
) -> None:
    """Set a value of a resolved document by dotted path (see `check_path`)."""
    keys, _ = check_path(doc, path, source, schema)
    node = doc
    for key in keys[:-1]:
        node = node[key]
    node[keys[-1]] = value


def is_list_valued(annotation: Any) -> bool:
    """Whether a field's value is itself a list (a vector such as `ball.pos`)."""
    while True:
        origin = typing.get_origin(annotation)
        if origin is typing.Annotated:
            annotation = typing.get_args(annotation)[0]
        elif origin in (typing.Union, types.UnionType):
            return any(
                is_list_valued(a) for a in typing.get_args(annotation) if a is not type(None)
            )
        else:
            return origin in (tuple, list)


def validate(
    doc: Mapping[str, Any],
    *,
    source: str,
    sweep_values: Mapping[str, Any],
    sweep_point: tuple[int, int] = (0, 1),
) -> RunSpec:
    """Validate a resolved document against the schema and build the `RunSpec`, which keeps
    `doc` as its document (hashed and logged): leave it unchanged afterwards.

    Raises:
        SpecError: the first problem, naming the file and the field.
    """
    spec = checked(SpecDocument, doc, source)
    bodies = tuple(
        Body.model_construct(
            **{
                **dict(body),
                "name": name,
                "rgba": body.rgba or tuple(BODY_PALETTE[index % len(BODY_PALETTE)]),
            }
        )
        for index, (name, body) in enumerate(spec.bodies.items())
    )
    return RunSpec(
        experiment=spec.name,
        description=spec.description,
        source=source,
        options=spec.options,
        contact=spec.contact,
        plane=spec.plane,
        bodies=bodies,
        stop=spec.stop,
        log_every=spec.logging.every,
        sweep_values=dict(sweep_values),
        sweep_index=sweep_point[0],
        sweep_size=sweep_point[1],
        document=doc,
    )


S = TypeVar("S", bound=Section)


def checked(schema: type[S], doc: Mapping[str, Any], source: str) -> S:
    """`doc` validated against `schema`.

    Raises:
        SpecError: the first problem, naming the file and the field.
    """
    try:
        return schema.model_validate(doc)
    except ValidationError as exc:
        raise schema_error(exc, source) from None
    except RecursionError:
        raise SpecError(source, "", "a value is nested too deeply") from None


def plain_copy(value: Any) -> Any:
    """A copy of a document of tables, lists and scalars (much faster than `copy.deepcopy`)."""
    if isinstance(value, list | tuple):
        return [plain_copy(v) for v in value]
    if isinstance(value, Mapping):
        return {k: plain_copy(v) for k, v in value.items()}
    return value


_WORDS = {  # pydantic's error types in our words: {input} is the value, the rest its context
    "missing": "is required",
    "float_type": "must be a number, got {input}",
    "int_type": "must be an integer, got {input}",
    "bool_type": "must be true or false, got {input}",
    "string_type": "must be a string, got {input}",
    "finite_number": "must be finite, got {input}",
    "greater_than": "must be > {gt:g}, got {input}",
    "greater_than_equal": "must be >= {ge:g}, got {input}",
    "less_than_equal": "must be <= {le:g}, got {input}",
    "literal_error": "must be one of {expected}, got {input}",
    "extra_forbidden": "unknown key",
    "model_type": "must be a table, got {input}",
    "dict_type": "must be a table, got {input}",
    "too_short": "must have at least {min_length} entries",
    "too_long": "must have at most {max_length} entries",
    "string_too_long": "must be at most {max_length} characters",
}


def schema_error(exc: ValidationError, source: str) -> SpecError:
    """The first error of a schema validation as a `SpecError` naming the dotted field."""
    err = exc.errors(include_url=False)[0]
    parts: list[str] = []
    for key in err["loc"]:
        if isinstance(key, int):
            parts[-1] = f"{parts[-1]}[{key}]"  # an item of a list
        elif key != "[key]":
            parts.append(str(key))
    ctx = err.get("ctx") or {}
    if err["type"] == "impactlab":
        if ctx.get("field"):
            parts.append(ctx["field"])
        text = ctx["text"]
    else:
        words = _WORDS.get(err["type"])
        text = words.format(input=short(err["input"]), **ctx) if words else err["msg"]
    return SpecError(source, ".".join(parts), text)
