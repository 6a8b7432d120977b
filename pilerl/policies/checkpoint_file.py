"""Verified checkpoint files: nothing read can run code, allocate without bound or be corrupt.

Every checkpoint pilerl writes (actors, behaviour-cloning runs, fine-tuning runs) is one
``torch.save`` zip holding a dict of tensors and plain values (str, int, float, bool,
None, lists, dicts) with ``format``, ``version`` and ``sha256`` keys. ``read_checkpoint``
checks, in this order, before anything is built from the content:

1. the file size (``MAX_CHECKPOINT_BYTES``) and the zip: every member stored
   uncompressed, their declared sizes within the file, every CRC-32 right (``torch.load``
   itself checks none of this: a flipped bit would load as different weights);
2. ``torch.load(weights_only=True)``: its unpickler builds tensors and plain containers
   only, so a pickled object is refused instead of run;
3. the content: only the types above, nested at most ``MAX_NESTING`` deep with at most
   ``MAX_ENTRIES`` entries, integers of at most 64 bits, every tensor a contiguous CPU
   tensor no larger than its storage, no NaN and no infinity (except where the caller
   allows infinity: a random forest's leaf thresholds);
4. the SHA-256 of the content (tensor bytes, shapes, dtypes and every value, in order)
   against the ``sha256`` written with it.

Every failure is a ``CheckpointError`` naming the file and the problem; torch's own
messages are never passed on (some advise loading with ``weights_only=False``, which
would run the pickled code).
"""

from __future__ import annotations

import hashlib
import json
import math
import pickle
import struct
import zipfile
from collections.abc import Callable, Collection
from pathlib import Path

import torch

from pilerl.io import atomic_path

DIGEST_KEY = "sha256"
MAX_CHECKPOINT_BYTES = 4 * 1024**3  # a fitted forest on a large dataset is ~0.5 GB
MAX_ZIP_MEMBERS = 100_000
MAX_NESTING = 32
MAX_ENTRIES = 1_000_000
MAX_INT_BITS = 64
MAX_TENSOR_ALIASING = 8  # tensor bytes may exceed the file bytes this much (shared storage)
MAX_JSON_CHARS = 10_000_000


class CheckpointError(ValueError):
    """A file is not a readable pilerl checkpoint; the message names the file and why."""


class CheckpointFormatError(CheckpointError):
    """A sound checkpoint file (zip and content types checked) of another ``format``."""


# ---------------------------------------------------------------- writing


def write_checkpoint(
    path: str | Path, payload: dict, *, allow_infinite: Callable[[str], bool] | None = None
) -> Path:
    """Write ``payload`` (with ``format`` and ``version``) atomically, with its SHA-256.

    The content is checked as ``read_checkpoint`` will check it, so nothing is written
    that could not be read back (a NaN weight fails here, naming its key).
    """
    path = Path(path)
    digest = _content_digest(path, payload, allow_infinite or _never, checking="write")
    with atomic_path(path) as tmp:
        torch.save({**payload, DIGEST_KEY: digest}, tmp)
    return path


# ---------------------------------------------------------------- reading


def read_checkpoint(
    path: str | Path,
    *,
    expected_format: str,
    version: int,
    legacy_versions: Collection[int] = (),
    allow_infinite: Callable[[str], bool] | None = None,
    what: str = "checkpoint",
    max_bytes: int = MAX_CHECKPOINT_BYTES,
) -> dict:
    """The verified payload of ``path`` (see the module docstring), without its digest.

    Args:
        expected_format: the ``format`` value the file must carry.
        version: the version this pilerl writes (must carry a digest).
        legacy_versions: older versions still read; they were written without a digest,
            so only the zip CRCs vouch for them.
        allow_infinite: ``where -> bool`` for the entries (``"state_dict/key"``) that
            may hold +-inf; NaN is refused everywhere.
        what: how the file is named in messages (``actor checkpoint``...).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such {what}")
    size = path.stat().st_size
    if size > max_bytes:
        raise CheckpointError(f"{path}: {size} bytes, larger than any {what} ({max_bytes})")
    _check_zip(path, size, what)
    payload = _unpickle_plain(path, what)
    if not isinstance(payload, dict) or payload.get("format") != expected_format:
        found = payload.get("format") if isinstance(payload, dict) else type(payload).__name__
        raise CheckpointFormatError(
            f"{path}: not a {what} (format {found!r}, expected {expected_format!r})"
        )
    found_version = payload.get("version")
    if found_version != version and found_version not in legacy_versions:
        raise CheckpointError(
            f"{path}: {what} version {found_version!r}; this pilerl reads "
            f"{sorted({version, *legacy_versions})}"
        )
    saved_digest = payload.pop(DIGEST_KEY, None)
    digest = _content_digest(path, payload, allow_infinite or _never, checking="read", size=size)
    if found_version == version and saved_digest != digest:
        raise CheckpointError(
            f"{path}: corrupted (the SHA-256 of its content does not match the one written with it)"
        )
    return payload


def parse_json(path: Path, text: object, field: str, *, allow_non_finite: bool = False) -> object:
    """``json.loads`` of a string entry, refusing oversized text and (unless allowed) NaN
    and infinities."""
    if not isinstance(text, str):
        raise CheckpointError(f"{path}: {field} is a {type(text).__name__}, not JSON text")
    if len(text) > MAX_JSON_CHARS:
        raise CheckpointError(f"{path}: {field} is longer than {MAX_JSON_CHARS} characters")

    def refuse(constant: str):
        raise CheckpointError(f"{path}: {field} holds {constant}")

    try:
        return json.loads(text, parse_constant=float if allow_non_finite else refuse)
    except (ValueError, RecursionError) as error:
        if isinstance(error, CheckpointError):
            raise
        raise CheckpointError(f"{path}: {field} is not valid JSON ({error})") from None


def load_optimizer_state(
    path: Path, optimizer: torch.optim.Optimizer, state: object, field: str
) -> None:
    """Load ``state`` into ``optimizer`` after checking it fits its parameters.

    ``Optimizer.load_state_dict`` checks the group sizes only: a moment tensor of the
    wrong shape would fail at the next step, deep in training.
    """
    if not isinstance(state, dict) or set(state) != {"state", "param_groups"}:
        raise CheckpointError(f"{path}: {field} is not an optimizer state")
    groups, own_groups = state["param_groups"], optimizer.param_groups
    if not isinstance(groups, list) or len(groups) != len(own_groups):
        raise CheckpointError(f"{path}: {field} has another number of parameter groups")
    parameters = {}
    for group, own in zip(groups, own_groups, strict=True):
        ids = group.get("params") if isinstance(group, dict) else None
        if not isinstance(ids, list) or len(ids) != len(own["params"]):
            raise CheckpointError(f"{path}: {field} has parameter groups of other sizes")
        parameters.update(zip(ids, own["params"], strict=True))
    entries = state["state"]
    if not isinstance(entries, dict):
        raise CheckpointError(f"{path}: {field} has no per-parameter state")
    for key, entry in entries.items():
        parameter = parameters.get(key)
        if parameter is None or not isinstance(entry, dict):
            raise CheckpointError(f"{path}: {field} has state for an unknown parameter {key!r}")
        for name, value in entry.items():
            if (
                isinstance(value, torch.Tensor)
                and value.dim() > 0
                and (value.shape != parameter.shape)
            ):
                raise CheckpointError(
                    f"{path}: {field}: {name} of parameter {key} has shape "
                    f"{tuple(value.shape)}, the parameter {tuple(parameter.shape)}"
                )
    try:
        optimizer.load_state_dict(state)
    except (ValueError, KeyError, TypeError, RuntimeError) as error:
        raise CheckpointError(f"{path}: {field} does not fit ({_first_line(error)})") from None


def load_module_state(
    path: Path, module: torch.nn.Module, state: object, field: str, *, assign: bool = False
) -> None:
    """``module.load_state_dict(state, strict=True)``, failures as ``CheckpointError``.

    ``assign=True`` (for a module built on the ``meta`` device) puts the tensors in
    place instead of copying them: names and shapes are checked all the same."""
    if not isinstance(state, dict):
        raise CheckpointError(f"{path}: {field} is not a state_dict")
    try:
        module.load_state_dict(state, strict=True, assign=assign)
    except (RuntimeError, ValueError, KeyError, TypeError) as error:
        raise CheckpointError(f"{path}: {field} ({_short(error)})") from None


# ---------------------------------------------------------------- the checks


def _never(where: str) -> bool:
    return False


def _first_line(error: BaseException) -> str:
    lines = str(error).strip().splitlines()
    line = lines[0] if lines else type(error).__name__
    return "(details withheld)" if "weights_only" in line else line[:300]


def _short(error: BaseException) -> str:
    text = " ".join(str(error).split())
    return "(details withheld)" if "weights_only" in text else text[:600]


def _check_zip(path: Path, size: int, what: str) -> None:
    """Stored members only, declared sizes within the file, every CRC-32 right."""
    try:
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
            if len(members) > MAX_ZIP_MEMBERS:
                raise CheckpointError(f"{path}: {len(members)} zip members; not a {what}")
            declared = 0
            for member in members:
                if member.compress_type != zipfile.ZIP_STORED or member.flag_bits & 0x1:
                    raise CheckpointError(
                        f"{path}: zip member {member.filename!r} is compressed or encrypted; "
                        f"pilerl never writes such a {what}"
                    )
                declared += member.file_size
            if declared > size:
                raise CheckpointError(
                    f"{path}: its zip members declare {declared} bytes in a {size}-byte file"
                )
            bad = archive.testzip()
    except CheckpointError:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, ValueError) as error:
        raise CheckpointError(
            f"{path}: not a readable {what} (truncated, or not a zip file: {_first_line(error)})"
        ) from None
    if bad is not None:
        raise CheckpointError(f"{path}: corrupted (CRC-32 mismatch in zip member {bad!r})")


def _unpickle_plain(path: Path, what: str) -> object:
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError:
        raise CheckpointError(
            f"{path}: not a readable {what}: it holds pickled Python objects besides tensors "
            "and plain values (refused: unpickling them could run code)"
        ) from None
    except Exception as error:  # noqa: BLE001 - torch raises many kinds; name the file
        raise CheckpointError(
            f"{path}: not a readable {what} ({type(error).__name__}: {_first_line(error)})"
        ) from None


def _content_digest(
    path: Path,
    payload: dict,
    allow_infinite: Callable[[str], bool],
    *,
    checking: str,
    size: int | None = None,
) -> str:
    """SHA-256 of ``payload``'s content, checking every entry on the way."""
    hasher = hashlib.sha256()
    budget = {"entries": 0, "tensor_bytes": 0}
    tensor_limit = None if size is None else MAX_TENSOR_ALIASING * size + 2**20

    def fail(problem: str):
        prefix = "" if checking == "read" else "cannot write: "
        raise CheckpointError(f"{path}: {prefix}{problem}")

    def visit(value: object, where: str, depth: int) -> None:
        budget["entries"] += 1
        if budget["entries"] > MAX_ENTRIES:
            fail(f"more than {MAX_ENTRIES} entries")
        if depth > MAX_NESTING:
            fail(f"nested deeper than {MAX_NESTING} levels at {where!r}")
        if isinstance(value, torch.Tensor):
            visit_tensor(value, where)
        elif isinstance(value, dict):
            hasher.update(b"D%d;" % len(value))
            for key, item in value.items():
                if not isinstance(key, str | int) or isinstance(key, bool):
                    fail(f"key {key!r} at {where!r} is not a str or int")
                visit_atom(key, where)
                visit(item, f"{where}/{key}" if where else str(key), depth + 1)
        elif isinstance(value, list | tuple):
            hasher.update(b"%s%d;" % (b"L" if isinstance(value, list) else b"U", len(value)))
            for index, item in enumerate(value):
                visit(item, f"{where}/{index}", depth + 1)
        else:
            visit_atom(value, where)

    def visit_atom(value: object, where: str) -> None:
        if value is None:
            hasher.update(b"N")
        elif isinstance(value, bool):
            hasher.update(b"b1" if value else b"b0")
        elif isinstance(value, int):
            if value.bit_length() > MAX_INT_BITS:
                fail(f"integer of {value.bit_length()} bits at {where!r}")
            hasher.update(b"I%d;" % value)
        elif isinstance(value, float):
            if math.isnan(value) or (math.isinf(value) and not allow_infinite(where)):
                fail(f"{value} at {where!r}")
            hasher.update(b"F" + struct.pack("<d", value))
        elif isinstance(value, str):
            data = value.encode("utf-8", "surrogatepass")
            hasher.update(b"S%d;" % len(data) + data)
        elif isinstance(value, bytes):
            hasher.update(b"B%d;" % len(value) + value)
        else:
            fail(f"unexpected {type(value).__name__} at {where!r}")

    def visit_tensor(tensor: torch.Tensor, where: str) -> None:
        if tensor.layout != torch.strided or tensor.device.type != "cpu" or tensor.is_quantized:
            fail(f"tensor {where!r} is not a dense CPU tensor")
        if not tensor.is_contiguous():
            fail(f"tensor {where!r} is not contiguous (shape {tuple(tensor.shape)})")
        nbytes = tensor.numel() * tensor.element_size()
        if tensor.untyped_storage().nbytes() < nbytes:
            fail(f"tensor {where!r} is larger than its storage")
        budget["tensor_bytes"] += nbytes
        if tensor_limit is not None and budget["tensor_bytes"] > tensor_limit:
            fail(f"its tensors add up to more than {MAX_TENSOR_ALIASING}x the file size")
        if tensor.is_floating_point() or tensor.is_complex():
            if bool(torch.isnan(tensor).any()):
                fail(f"NaN in {where!r}")
            if not allow_infinite(where) and bool(torch.isinf(tensor).any()):
                fail(f"infinite value in {where!r}")
        header = f"T{tensor.dtype};{tuple(tensor.shape)};".encode()
        hasher.update(header)
        hasher.update(tensor.detach().reshape(-1).view(torch.uint8).numpy())

    try:
        visit(payload, "", 0)
    except RecursionError:
        fail("nested too deeply")
    return hasher.hexdigest()
