"""The handles file of `spacewarp edit`, read in Python: spacewarp.load_handles."""

from __future__ import annotations

import json
import os
from typing import Any, Union

import numpy as np
from numpy.typing import NDArray

from ._spacewarp import InvalidInput, IoError, _check_handle_regions


class _Located(Exception):
    """A problem of the file's JSON text, before it has a key path."""


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    seen: dict[str, Any] = {}
    for key, value in pairs:
        if key in seen:
            raise _Located(f"key '{key}' is given twice")
        seen[key] = value
    return seen


def _refuse_constant(name: str) -> float:
    # json accepts NaN and Infinity, which are not JSON (and not what the CLI's reader takes).
    raise _Located(f"{name} is not a JSON number")


def _read_json(path: Union[str, "os.PathLike[str]"], where: str) -> Any:
    try:
        with open(path, "rb") as stream:
            raw = stream.read()
    except OSError as error:
        raise IoError(f"{where}: cannot read the handles file ({error.strerror or error})") \
            from None
    try:
        return json.loads(raw.decode("utf-8"), object_pairs_hook=_no_duplicates,
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


def load_handles(path: Union[str, "os.PathLike[str]"]) -> list[dict[str, NDArray[Any]]]:
    """The handle regions of a handles file, as `spacewarp edit --handles` reads it.

    The file is JSON: ``{"handles": [REGION, ...]}``, each region
    ``{"vertices": [i, ...], "matrix": [[4 numbers] x 4 rows]}`` (the vertices move by that
    affine map, last row 0 0 0 1; the identity pins them) or
    ``{"vertices": [i, ...], "targets": [[x, y, z], ...]}`` (one target per vertex, world units).
    Indices are the model's vertices in file order.

    Returns a list of dicts ``{"vertices": (k,) uint32, "matrix": (4, 4) float64}`` or
    ``{"vertices": (k,) uint32, "targets": (k, 3) float64}``, as :func:`edit` and
    :func:`resolve_handles` take them (which check the indices against the model, and the
    matrices and target counts). Raises IoError when the file cannot be read or is not JSON, and
    InvalidInput naming the file and the key path at fault ("edit.json: handles[2].vertices[5]:
    index -1 is negative") for content that is not a handles file.
    """
    where = os.fspath(path)
    content = _read_json(path, where)
    if not isinstance(content, dict):
        raise InvalidInput(f"{where}: must be an object {{\"handles\": [...]}}")
    for key in content:
        if key != "handles":
            raise InvalidInput(f"{where}: unknown key '{key}' (the key: handles)")
    handles = content.get("handles")
    if not isinstance(handles, list):
        raise InvalidInput(f"{where}: handles: " + ("no 'handles'" if handles is None else
                                                    "must be an array of regions"))
    if not handles:
        raise InvalidInput(f"{where}: handles: no handle region (give at least one)")
    for k, region in enumerate(handles):
        if not isinstance(region, dict):
            raise InvalidInput(f"{where}: handles[{k}] must be an object with 'vertices' and "
                               "'matrix' or 'targets'")
    _check_handle_regions(handles, f"{where}: handles")
    return [{key: np.asarray(value, dtype=np.uint32 if key == "vertices" else np.float64)
             for key, value in region.items()} for region in handles]
