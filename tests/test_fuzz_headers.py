"""Camera-file header parsers under attack: bit flips, truncations and random bytes.

Whatever the bytes, opening a file and reading it either works or raises
:class:`grainplug.errors.MovieError` (one clear line): never another exception, never a
hang, never a huge allocation. Real headers from ../shared/camera-samples are the seeds
where present, files written from the published layouts otherwise.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from camera_writers import write_cine, write_mraw, write_seq
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from grainplug.errors import MovieError
from grainplug.readers import open_movie

SAMPLES = Path(__file__).resolve().parent.parent.parent / "shared" / "camera-samples"
EXAMPLES = int(os.environ.get("GRAINPLUG_FUZZ_EXAMPLES", "60"))


def seeds(folder: Path) -> dict[str, bytes]:
    """Small camera files to mutate: real samples' heads where available, plus written ones."""
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 1024, (4, 8, 16)).astype(np.uint16)
    out = {
        "p10.cine": write_cine(folder / "a.cine", frames, layout="p10", stamps_s=1.6e9 + np.arange(4) / 100,
                               decimation=2.0).read_bytes(),
        "16.cine": write_cine(folder / "b.cine", frames, flip_v=True).read_bytes(),
        "8.seq": write_seq(folder / "c.seq", frames.astype(np.uint8), stamps_s=1.7e9 + np.arange(4) / 50).read_bytes(),
    }
    write_mraw(folder / "d", frames & 0xFFF, bits=12, cihx=True)
    out["12.cihx"] = (folder / "d.cihx").read_bytes()
    out["12.mraw"] = (folder / "d.mraw").read_bytes()
    for name in ("pims/cine_781.cine", "pyidi/data_small_cine.cine", "pims/sample_norpix6.seq"):
        path = SAMPLES / name
        if path.exists():
            data = path.read_bytes()
            out[Path(name).name] = data[:300_000]  # the headers and the first frames; the rest is cut
    return out


def attempt(path: Path, **kw: object) -> None:
    """Open and read everything; only MovieError may come out."""
    try:
        with open_movie(path, **kw) as movie:
            info = movie.info
            assert info.n_frames >= 1 and info.width >= 1 and info.height >= 1
            for k in {0, info.n_frames - 1}:
                frame = movie.read(k)
                assert frame.shape[:2] == (info.height, info.width)
    except MovieError as exc:
        text = str(exc)
        assert "\n" not in text and len(text) < 600, text


@pytest.fixture(scope="module")
def seed_files(tmp_path_factory) -> dict[str, bytes]:
    return seeds(tmp_path_factory.mktemp("seeds"))


SUFFIX = {"p10.cine": ".cine", "16.cine": ".cine", "8.seq": ".seq", "cine_781.cine": ".cine",
          "data_small_cine.cine": ".cine", "sample_norpix6.seq": ".seq"}


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.sampled_from(sorted(SUFFIX)), flips=st.lists(st.tuples(st.integers(0, 12_000), st.integers(0, 7)),
                                                             min_size=1, max_size=8),
       cut=st.one_of(st.none(), st.integers(0, 20_000)), allow=st.booleans())
def test_bit_flips_and_cuts_in_cine_and_seq_headers(tmp_path, seed_files, which, flips, cut, allow):
    if which not in seed_files:
        return  # a real sample absent on this machine
    data = bytearray(seed_files[which])
    for pos, bit in flips:
        if pos < len(data):
            data[pos] ^= 1 << bit
    if cut is not None:
        data = data[:cut]
    path = tmp_path / f"fuzz{SUFFIX[which]}"
    path.write_bytes(bytes(data))
    attempt(path, allow_truncated=allow)


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(max_size=400), keep_data=st.booleans())
def test_random_photron_headers(tmp_path, seed_files, text, keep_data):
    header = tmp_path / "m.cih"
    header.write_text(text, encoding="utf-8", errors="replace")
    if keep_data:
        (tmp_path / "m.mraw").write_bytes(seed_files["12.mraw"])
    attempt(header)


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(edits=st.lists(st.tuples(st.integers(0, 1500), st.sampled_from(list(b"0123456789-<>/ x\x00"))),
                      min_size=1, max_size=6))
def test_edited_cihx_headers(tmp_path, seed_files, edits):
    data = bytearray(seed_files["12.cihx"])
    for pos, byte in edits:
        if pos < len(data):
            data[pos] = byte
    (tmp_path / "m.cihx").write_bytes(bytes(data))
    (tmp_path / "m.mraw").write_bytes(seed_files["12.mraw"])
    attempt(tmp_path / "m.cihx")


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(min_size=1, max_size=3000), suffix=st.sampled_from([".cine", ".seq", ".mraw", ".avi"]),
       magic=st.sampled_from([b"", b"CI", b"\xed\xfe\x00\x00"]))
def test_random_bytes(tmp_path, data, suffix, magic):
    path = tmp_path / f"r{suffix}"
    path.write_bytes(magic + data)
    if suffix == ".mraw":
        (tmp_path / "r.cih").write_text("Image Width : 8\nImage Height : 8\nTotal Frame : 3\nColor Bit : 16\n")
    attempt(path)
