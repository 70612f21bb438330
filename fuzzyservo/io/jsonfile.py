"""JSON output files: strict JSON (NaN and inf become null), numpy numbers as Python ones."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from fuzzyservo.atomic import write_text
from fuzzyservo.results import json_ready

__all__ = ["json_ready", "read_json", "write_json"]


def write_json(path: str | Path, payload: Any) -> Path:
    """Write ``payload`` (a result object: its ``to_dict()``) as indented strict JSON, creating
    the folder (whole or not at all: :func:`~fuzzyservo.atomic.atomic_write`)."""
    if hasattr(payload, "to_dict"):
        payload = payload.to_dict()
    return write_text(path, json.dumps(json_ready(payload), indent=2, allow_nan=False) + "\n")


def read_json(path: str | Path) -> Any:
    """A JSON file written by :func:`write_json` (null stays None)."""
    return json.loads(Path(path).read_text(encoding="utf-8"))
