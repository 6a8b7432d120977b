"""Issue #13, importer part: bad input ends in a clear error naming the place, a non-zero
exit and nothing half-written; YAML mappings cannot blow up or silently change meaning."""

from __future__ import annotations

import gzip
import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from pilerl.data.importers import (
    LogImportError,
    MappingError,
    create_store,
    import_logs,
    load_mapping,
)
from pilerl.data.importers.__main__ import main
from pilerl.data.store import EpisodeStore

MAPPING = """\
sensors:
  boom_angle: {column: th1, unit: rad, range: [-1, 1]}
controls:
  boom: {column: u}
time: {column: t_ms, scale: 0.001}
"""


def write_mapping(path: Path, text: str = MAPPING) -> Path:
    path.write_text(text)
    return path


def tiny_csv(path: Path, n: int = 20) -> Path:
    rows = "".join(f"{10 * i},{0.01 * (i % 50)},{0.02 * (i % 50)}\n" for i in range(n))
    path.write_text("t_ms,th1,u\n" + rows)
    return path


def run_cli(*args: str) -> tuple[int, str]:
    """(exit status, error message) of the command line, run in this process."""
    try:
        main(list(args))
    except SystemExit as exit_:
        code = exit_.code
        return (1, code) if isinstance(code, str) else (code or 0, "")
    return 0, ""


def test_command_line_exits_1_without_traceback(tmp_path):
    mapping = write_mapping(tmp_path / "m.yaml")
    (tmp_path / "log.csv").write_text("t_ms,th1,u\n0,0.1,0\n10,0.2")
    result = subprocess.run(
        [sys.executable, "-m", "pilerl.data.importers", "--mapping", str(mapping)]
        + ["--dataset", str(tmp_path / "ds"), str(tmp_path / "log.csv")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 1
    assert result.stderr.startswith(f"error: {tmp_path / 'log.csv'}: row 2 (1-based data row)")
    assert "truncated file" in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "ds").exists()


# ------------------------------------------------------------------ YAML mappings
def test_duplicate_yaml_key_is_refused_naming_both_lines(tmp_path):
    # the second `time:` silently replaced the time column with a synthetic 3 Hz base
    path = write_mapping(tmp_path / "m.yaml", MAPPING + "time: {rate_hz: 3.0}\n")
    with pytest.raises(MappingError, match=r"line 6: duplicate key 'time' \(first at line 5\)"):
        load_mapping(path)


def test_duplicate_nested_key_is_refused(tmp_path):
    text = MAPPING.replace("{column: u}", "{column: u, column: v}")
    with pytest.raises(MappingError, match="duplicate key 'column'"):
        load_mapping(write_mapping(tmp_path / "m.yaml", text))


def test_yaml_alias_bomb_is_refused_quickly(tmp_path):
    levels = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for k in range(1, 9):
        prev = chr(ord("a") + k - 1)
        name = chr(ord("a") + k)
        levels.append(f"{name}: &{name} [{', '.join(['*' + prev] * 9)}]")
    bomb = write_mapping(tmp_path / "bomb.yaml", "\n".join(levels) + "\n")
    assert bomb.stat().st_size < 1200
    with pytest.raises(MappingError, match="aliases"):
        load_mapping(bomb)


def test_few_expanding_aliases_are_refused_by_size(tmp_path):
    # under the alias count, but 10**6 values once expanded
    text = "a: &a [" + ", ".join(["1"] * 100) + "]\n"
    text += "b: &b [" + ", ".join(["*a"] * 100) + "]\n"
    text += "c: [" + ", ".join(["*b"] * 100) + "]\n"
    with pytest.raises(MappingError, match="aliases"):
        load_mapping(write_mapping(tmp_path / "m.yaml", text))


def test_utf16_mapping_with_bom_loads_and_bad_bytes_are_named(tmp_path):
    path = tmp_path / "m16.yaml"
    path.write_bytes(MAPPING.encode("utf-16"))
    assert load_mapping(path).time.column == "t_ms"
    bad = tmp_path / "latin.yaml"
    bad.write_bytes(MAPPING.replace("th1", "th\xb0").encode("latin-1"))
    with pytest.raises(MappingError, match=r"line 2: not UTF-8 text \(byte 0xb0"):
        load_mapping(bad)


@pytest.mark.parametrize(
    ("params", "problem"),
    [
        ("{moisture: .nan}", r"condition_params\.moisture: nan is not a finite number"),
        ("{moisture: .inf}", r"condition_params\.moisture: inf is not a finite number"),
        ("{day: 2025-02-11}", r"condition_params\.day: datetime\.date\(2025, 2, 11\) .* quote"),
        ("{layers: [1, -.inf]}", r"condition_params\.layers\[1\]: -inf"),
    ],
)
def test_condition_params_must_be_plain_json(tmp_path, params, problem):
    text = MAPPING + f"metadata: {{condition: x, condition_params: {params}}}\n"
    with pytest.raises(MappingError, match=problem):
        load_mapping(write_mapping(tmp_path / "m.yaml", text))


def test_cli_bad_condition_params_leave_no_dataset(tmp_path):
    text = MAPPING + "metadata: {condition: x, condition_params: {moisture: .nan}}\n"
    mapping = write_mapping(tmp_path / "m.yaml", text)
    log = tiny_csv(tmp_path / "log.csv")
    with pytest.raises(SystemExit, match="not a finite number"):
        main(["--mapping", str(mapping), "--dataset", str(tmp_path / "ds"), str(log)])
    assert not (tmp_path / "ds").exists()


# ------------------------------------------------------------------ compressed logs
def test_truncated_and_corrupt_gzip_are_reported(tmp_path):
    mapping = load_mapping(write_mapping(tmp_path / "m.yaml"))
    text = tiny_csv(tmp_path / "plain.csv", n=2000).read_bytes()
    truncated = tmp_path / "cut.csv.gz"
    truncated.write_bytes(gzip.compress(text)[:-200])
    corrupt = tmp_path / "flip.csv.gz"
    data = bytearray(gzip.compress(text))
    data[40:60] = bytes(20)
    corrupt.write_bytes(bytes(data))
    not_gzip = tmp_path / "plain.csv.gz"
    not_gzip.write_bytes(text)
    store = create_store(tmp_path / "ds", mapping)
    for path, problem in [
        (truncated, "truncated gzip archive"),
        (corrupt, "corrupt gzip archive"),
        (not_gzip, "corrupt gzip archive"),
    ]:
        with pytest.raises(LogImportError, match=problem) as error:
            import_logs(path, mapping, store)
        assert str(path) in str(error.value)
    assert len(store) == 0
    good = tmp_path / "good.csv.gz"
    good.write_bytes(gzip.compress(text))
    assert [m.n_samples for m in import_logs(good, mapping, store)] == [2000]


# ------------------------------------------------------------------ HDF5 dtypes
@pytest.mark.parametrize(
    ("make", "kind"),
    [
        (lambda g: g.create_dataset("th1", data=np.void(b"\x00" * 8).repeat(20)), "opaque"),
        (
            lambda g: g.create_dataset("th1", data=np.zeros(20, dtype=[("a", "f4"), ("b", "i4")])),
            "compound",
        ),
        (lambda g: g.create_dataset("th1", data=np.zeros(20, dtype=np.complex64)), "complex"),
        (
            lambda g: g.create_dataset("th1", (20,), dtype=h5py.vlen_dtype(np.float32)),
            "variable-length",
        ),
    ],
)
def test_unsupported_hdf5_dtypes_are_refused_naming_the_column(tmp_path, make, kind):
    path = tmp_path / "log.h5"
    with h5py.File(path, "w") as h5:
        h5.create_dataset("t_ms", data=np.arange(20) * 10.0)
        h5.create_dataset("u", data=np.zeros(20))
        make(h5)
    mapping = load_mapping(write_mapping(tmp_path / "m.yaml"))
    with pytest.raises(LogImportError, match=f"unsupported HDF5 dtype .*{kind}") as error:
        import_logs(path, mapping, create_store(tmp_path / "ds", mapping))
    assert error.value.column == "th1"


def test_hdf5_declaring_a_huge_length_is_refused_before_reading(tmp_path):
    # a dataset whose header claims 10**9 rows and holds none: reading it allocated
    # gigabytes of fill values
    path = tmp_path / "huge.h5"
    with h5py.File(path, "w") as h5:
        h5.create_dataset("t_ms", shape=(10**9,), dtype="f8", chunks=(1024,))
        h5.create_dataset("th1", data=np.zeros(20))
        h5.create_dataset("u", data=np.zeros(20))
    assert path.stat().st_size < 1 << 20
    mapping = load_mapping(write_mapping(tmp_path / "m.yaml"))
    with pytest.raises(LogImportError, match="declares 1000000000 rows"):
        import_logs(path, mapping, create_store(tmp_path / "ds", mapping))


def test_unterminated_quote_is_reported_not_swallowed(tmp_path):
    path = tmp_path / "q.csv"
    path.write_text('t_ms,th1,u\n0,0.1,0\n10,"0.2,0\n20,0.3,0\n')
    mapping = load_mapping(write_mapping(tmp_path / "m.yaml"))
    with pytest.raises(LogImportError, match="unreadable CSV"):
        import_logs(path, mapping, create_store(tmp_path / "ds", mapping))


# ------------------------------------------------------------------ broken dataset folders
BROKEN_INDEXES = {
    "not_json": "{",
    "a_list": "[]",
    "no_episodes": json.dumps({"schema_version": 1, "sensors": {}, "controls": []}),
    "old_version": json.dumps({"schema_version": 0}),
}


@pytest.mark.parametrize("case", [*BROKEN_INDEXES, "no_episodes_folder", "a_file"])
def test_cli_refuses_broken_dataset_folders_cleanly(tmp_path, case):
    mapping = write_mapping(tmp_path / "m.yaml")
    log = tiny_csv(tmp_path / "log.csv")
    dataset = tmp_path / "ds"
    if case == "a_file":
        dataset.write_text("not a folder")
    elif case == "no_episodes_folder":
        create_store(dataset, load_mapping(mapping))
        (dataset / "episodes").rmdir()
    else:
        dataset.mkdir()
        (dataset / "index.json").write_text(BROKEN_INDEXES[case])
    before = sorted(p.name for p in tmp_path.rglob("*"))
    code, message = run_cli("--mapping", str(mapping), "--dataset", str(dataset), str(log))
    assert code == 1
    assert message.startswith("error: ") and str(dataset) in message
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


def test_cli_bad_log_into_new_dataset_leaves_nothing(tmp_path):
    mapping = write_mapping(tmp_path / "m.yaml")
    good = tiny_csv(tmp_path / "good.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text(good.read_text().replace("0.05,", "x,", 1))
    code, message = run_cli(
        "--mapping", str(mapping), "--dataset", str(tmp_path / "ds"), str(good), str(bad)
    )
    assert code == 1
    assert message == (
        f"error: {bad}: column 'th1', row 6 (1-based data row) at line 7: non-numeric value 'x'"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv", "good.csv", "m.yaml"]


def test_cli_bad_log_into_existing_dataset_changes_nothing(tmp_path):
    mapping_path = write_mapping(tmp_path / "m.yaml")
    good = tiny_csv(tmp_path / "good.csv")
    assert (
        run_cli("--mapping", str(mapping_path), "--dataset", str(tmp_path / "ds"), str(good))[0]
        == 0
    )
    index = (tmp_path / "ds" / "index.json").read_bytes()
    imports = (tmp_path / "ds" / "imports.json").read_bytes()
    bad = tmp_path / "bad.csv"
    bad.write_text(good.read_text()[:-3])  # cut inside the last row
    code, message = run_cli(
        "--mapping", str(mapping_path), "--dataset", str(tmp_path / "ds"), str(bad)
    )
    assert code == 1 and "truncated file" in message
    assert (tmp_path / "ds" / "index.json").read_bytes() == index
    assert (tmp_path / "ds" / "imports.json").read_bytes() == imports
    assert len(EpisodeStore.open(tmp_path / "ds")) == 1
