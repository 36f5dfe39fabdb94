"""The handles file of `spacewarp edit`, read in Python: spacewarp.load_handles."""

from __future__ import annotations

import json
import math
import os
from typing import Any, Union

import numpy as np
from numpy.typing import NDArray

from ._spacewarp import InvalidInput, IoError

_REGION_KEYS = ("vertices", "matrix", "targets")


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    seen: dict[str, Any] = {}
    for key, value in pairs:
        if key in seen:
            raise _Located(f"key '{key}' is given twice")
        seen[key] = value
    return seen


class _Located(Exception):
    """A problem of the file's content, before the key path is known."""


def _refuse_constant(name: str) -> float:
    # json accepts NaN and Infinity, which are not JSON (and not what the CLI's reader takes).
    raise _Located(f"{name} is not a JSON number")


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidInput(f"{where}: must be a number, not {json.dumps(value)[:40]}")
    if not math.isfinite(float(value)):
        raise InvalidInput(f"{where}: is not finite")
    return float(value)


def _rows(value: Any, where: str, count: int | None) -> NDArray[np.float64]:
    """An array of rows of three (targets) or four (matrix) numbers."""
    width = 3 if count is None else 4
    if not isinstance(value, list):
        raise InvalidInput(f"{where}: must be an array of [{', '.join('xyzw'[:width])}] rows")
    if count is not None and len(value) != count:
        raise InvalidInput(f"{where}: must have {count} rows, not {len(value)}")
    rows = []
    for i, row in enumerate(value):
        if not isinstance(row, list) or len(row) != width:
            raise InvalidInput(f"{where}[{i}]: must be an array of {width} numbers")
        rows.append([_number(x, f"{where}[{i}][{j}]") for j, x in enumerate(row)])
    return np.array(rows, dtype=np.float64).reshape(-1, width)


def _region(value: Any, where: str) -> dict[str, NDArray[Any]]:
    if not isinstance(value, dict):
        raise InvalidInput(f"{where}: must be an object with 'vertices' and 'matrix' or 'targets'")
    for key in value:
        if key not in _REGION_KEYS:
            raise InvalidInput(f"{where}: unknown key '{key}' (the keys: {', '.join(_REGION_KEYS)})")
    if "vertices" not in value:
        raise InvalidInput(f"{where}: no 'vertices'")
    if ("matrix" in value) == ("targets" in value):
        raise InvalidInput(f"{where}: " + ("give 'matrix' or 'targets', not both" if "matrix" in value
                                           else "needs 'matrix' or 'targets'"))
    vertices = value["vertices"]
    if not isinstance(vertices, list):
        raise InvalidInput(f"{where}.vertices: must be an array of vertex indices")
    for j, index in enumerate(vertices):
        if isinstance(index, bool) or not isinstance(index, int):
            raise InvalidInput(f"{where}.vertices[{j}]: must be an integer vertex index, not "
                               f"{json.dumps(index)[:40]}")
        if not 0 <= index < 2**32:
            raise InvalidInput(f"{where}.vertices[{j}]: {index} is not a vertex index")
    region: dict[str, NDArray[Any]] = {"vertices": np.array(vertices, dtype=np.uint32)}
    if "matrix" in value:
        region["matrix"] = _rows(value["matrix"], f"{where}.matrix", 4)
    else:
        region["targets"] = _rows(value["targets"], f"{where}.targets", None)
    return region


def load_handles(path: Union[str, "os.PathLike[str]"]) -> list[dict[str, NDArray[Any]]]:
    """The handle regions of a handles file, as `spacewarp edit --handles` reads it.

    The file is JSON: ``{"handles": [REGION, ...]}``, each region
    ``{"vertices": [i, ...], "matrix": [[4 numbers] x 4 rows]}`` (the vertices move by that
    affine map, last row 0 0 0 1; the identity pins them) or
    ``{"vertices": [i, ...], "targets": [[x, y, z], ...]}`` (one target per vertex, world units).
    Indices are the model's vertices in file order.

    Returns a list of dicts ``{"vertices": (k,) uint32, "matrix": (4, 4) float64}`` or
    ``{"vertices": (k,) uint32, "targets": (k, 3) float64}``, as :func:`edit` and
    :func:`resolve_handles` take them (which check the indices against the model and the
    matrices and target counts). Raises IoError when the file cannot be read or is not JSON, and
    InvalidInput naming the file and the key path at fault ("edit.json: handles[2].vertices[5]:
    ...") for content that is not a handles file.
    """
    where = os.fspath(path)
    try:
        with open(path, "rb") as stream:
            raw = stream.read()
    except OSError as error:
        raise IoError(f"{where}: cannot read the handles file ({error.strerror or error})") from None
    try:
        text = raw.decode("utf-8")
        content = json.loads(text, object_pairs_hook=_no_duplicates,
                             parse_constant=_refuse_constant)
    except UnicodeDecodeError as error:
        raise IoError(f"{where}: not valid JSON: not UTF-8 text at byte {error.start}") from None
    except json.JSONDecodeError as error:
        raise IoError(f"{where}: not valid JSON: line {error.lineno}, column {error.colno}: "
                      f"{error.msg}") from None
    except _Located as error:
        raise IoError(f"{where}: not valid JSON: {error}") from None
    except RecursionError:
        raise IoError(f"{where}: not valid JSON: nested too deeply") from None
    if not isinstance(content, dict):
        raise InvalidInput(f"{where}: must be an object {{\"handles\": [...]}}")
    for key in content:
        if key != "handles":
            raise InvalidInput(f"{where}: unknown key '{key}' (the key: handles)")
    if "handles" not in content:
        raise InvalidInput(f"{where}: no 'handles'")
    handles = content["handles"]
    if not isinstance(handles, list):
        raise InvalidInput(f"{where}: handles: must be an array of regions")
    if not handles:
        raise InvalidInput(f"{where}: handles: no handle region (give at least one)")
    return [_region(region, f"{where}: handles[{k}]") for k, region in enumerate(handles)]
