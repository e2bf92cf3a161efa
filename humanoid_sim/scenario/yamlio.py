"""Reading YAML files strictly: plain data only (no object construction), no duplicate keys."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from humanoid_sim.scenario.fields import ScenarioError


class _StrictSafeLoader(yaml.SafeLoader):
    """PyYAML's safe loader (plain data only, no object construction) that also rejects duplicate keys."""


def _construct_mapping(loader: _StrictSafeLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    seen: set = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            dup = key in seen
        except TypeError:  # unhashable key: let the base constructor report it
            break
        if dup:
            raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r}", key_node.start_mark)
        seen.add(key)
    return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)


_StrictSafeLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def read_yaml(path: str | Path, what: str = "scenario file", error: type[Exception] = ScenarioError) -> Any:
    """The YAML document of a file, read strictly (plain data only, no duplicate keys); ``what`` names the file
    in messages, ``error`` is raised for a missing, unreadable or invalid file."""
    p = Path(path)
    if not p.exists():
        raise error(f"{p}: no such {what}")
    if not p.is_file():
        raise error(f"{p}: not a regular file")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{p}: cannot read as UTF-8 text: {exc}") from None
    try:
        return yaml.load(text, Loader=_StrictSafeLoader)  # noqa: S506 (a SafeLoader subclass)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        if isinstance(exc, yaml.constructor.ConstructorError) and "constructor for the tag" in problem:
            problem += " (only plain YAML data is accepted; tags that construct objects are refused)"
        raise error(f"{p}: not valid YAML{where}: {problem}") from None
