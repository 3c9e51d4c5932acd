"""Every reader keeps the movie protocol, whatever the format.

Through the public calls only (:func:`open_movie`, ``info``, ``frames``, ``read``,
``sample``, ``read_band``): the contract over every format the synthetic writer
produces and over frames in memory, then the layouts that once went wrong — raw
video read straight from the file, rows stored bottom-up, BigTIFF, seeking in
compressed video.
"""

from __future__ import annotations

import struct

import av
import numpy as np
import pytest
import tifffile
from conftest import grey
from warned import codes, of_code

from grainplug.band import Band
from grainplug.errors import MovieError
from grainplug.readers import open_movie
from grainplug.readers.base import map_file, read_file
from grainplug.readers.cvvideo import OpenCVVideoMovie
from grainplug.synthetic import FORMATS, MovieWriter, SynthConfig, synthesize
from grainplug.synthetic.render import Renderer

N, WIDTH, HEIGHT, FPS = 24, 64, 160, 250.0

#: how each format is written for the contract: (rgb, bit depth) — a spread of what each stores
CONTRACT = {
    "tiff": (True, 8),
    "png": (False, 16),
    "tiff-folder": (True, 16),
    "bmp": (False, 8),
    "jpeg": (True, 8),
    "avi": (True, 8),
    "mjpeg": (True, 8),
    "ffv1": (True, 16),
    "mov": (True, 8),
    "h264": (True, 8),
    "mraw": (False, 8),  # written grey
    "cine": (False, 16),  # written grey, 16-bit
    "seq": (True, 8),  # B-G-R colour, time-stamped
}
#: mean absolute grey error of lossy formats (8-bit levels, noise sigma 3)
LOSSY_MEAN_ERR = 5.0


def random_band(rng: np.random.Generator, shape: tuple[int, int], n_pos: int = 50, n_across: int = 5) -> Band:
    """Pixels spread over the whole frame, random positive weights summing to 1 per position."""
    rows = rng.integers(0, shape[0], (n_pos, n_across))
    cols = rng.integers(0, shape[1], (n_pos, n_across))
    w = rng.uniform(0.05, 1.0, (n_pos, n_across)).astype(np.float32)
    return Band(rows, cols, w / w.sum(axis=1, keepdims=True), shape)


#: formats stored as YUV: ``read_band`` gives their luma, not the mean of the decoded RGB channels
LUMA = {"h264", "mjpeg"}
#: luma against the channel mean of the same decoded frames: rms residual of an affine fit (grey levels)
LUMA_AFFINE_RMS = 1.0
#: and the offset of that fit: none but the codec's (grey levels)
LUMA_OFFSET = 3.0


def check_band(movie, frames: list[np.ndarray], rng: np.random.Generator, *, luma: bool = False) -> None:
    """``read_band`` gives the plain profiles of ``frames``, whatever the threads.

    For YUV-coded video it gives the luma plane as decoded (no colour conversion), which is an
    affine function of the channel mean for the scenes grainplug films (grey or uniformly tinted):
    checked as such, tightly.
    """
    band = random_band(rng, (movie.info.height, movie.info.width))
    want = np.stack([band.profile(f) for f in frames])
    one = movie.read_band(band, threads=1)
    movie.prefetch()  # as the analysis does: the read-ahead runs while the band is read
    two = movie.read_band(band, threads=2)
    assert one.dtype == np.float32 and one.shape == want.shape
    np.testing.assert_array_equal(one, two)
    if not luma:
        np.testing.assert_allclose(one, want, rtol=1e-5, atol=1e-4)
        return
    design = np.stack([want.ravel(), np.ones(want.size)], axis=1)
    coef, *_ = np.linalg.lstsq(design, one.ravel().astype(float), rcond=None)
    rms = np.sqrt(np.mean((design @ coef - one.ravel()) ** 2))
    # full range, as a conversion to grey gives: no offset (limited-range luma, 16-235, read as such had 16)
    assert 0.8 < coef[0] < 1.2 and abs(coef[1]) < LUMA_OFFSET and rms < LUMA_AFFINE_RMS, (coef, rms)


def check_contract(movie, truth: np.ndarray, fps: float | None, lossless: bool, rng: np.random.Generator, *,
                   luma: bool = False) -> None:
    n = len(truth)
    info = movie.info
    every = list(movie.frames())
    assert info.n_frames == len(movie) == len(every) == n
    assert info.frame_shape == truth.shape[1:] == every[0].shape
    assert info.dtype == truth.dtype.name
    assert all(f.shape == truth.shape[1:] and f.dtype == truth.dtype for f in every)
    assert info.fps == (pytest.approx(fps) if fps else None)
    if lossless:
        for k, (got, exp) in enumerate(zip(every, truth, strict=True)):
            np.testing.assert_array_equal(got, exp, err_msg=f"frame {k}")
    else:
        err = np.mean([np.abs(grey(g) - grey(e)).mean() for g, e in zip(every, truth, strict=True)])
        assert err < LOSSY_MEAN_ERR
    for k in (n - 1, 0, 1, n // 2):
        np.testing.assert_array_equal(movie.read(k), every[k], err_msg=f"read({k})")
    with pytest.raises(IndexError):
        movie.read(n)
    for start, stop, step in ((3, 20, 4), (0, None, 5), (n - 2, n + 10, 1), (7, 8, 1), (n, None, 1), (5, 2, 1)):
        got = list(movie.frames(start, stop, step))
        want = every[start:stop:step]
        assert len(got) == len(want), (start, stop, step)
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(a, b)
    check_band(movie, every, rng, luma=luma)


def _skip_without_writer(fmt: str) -> None:
    if fmt == "h264" and "libx264" not in av.codecs_available:
        pytest.skip("this FFmpeg has no libx264 encoder for the h264 writer")


def test_contract_covers_every_format():
    assert set(CONTRACT) == set(FORMATS)


@pytest.mark.parametrize("fmt", sorted(CONTRACT))
def test_reader_contract(tmp_path, fmt):
    _skip_without_writer(fmt)
    rgb, depth = CONTRACT[fmt]
    cfg = SynthConfig(n_frames=N, width_px=WIDTH, height_px=HEIGHT, fps=FPS, rgb=rgb, bit_depth=depth, seed=4)
    movie = synthesize(cfg, tmp_path, fmt=fmt).movie
    truth = np.stack(list(Renderer(cfg).frames()))
    spec = FORMATS[fmt]
    with open_movie(movie) as m:
        # image folders hold no frame rate; files hold the one written
        check_contract(m, truth, FPS if spec.suffix else None, spec.lossless, np.random.default_rng(1),
                       luma=fmt in LUMA)


#: video formats as the contract writes them for the OpenCV reader (the default install's, without PyAV):
#: what it reads as stored (8-bit colour, 8- and 16-bit grey)
OPENCV_CONTRACT = {"avi": (True, 8), "mjpeg": (True, 8), "ffv1": (False, 16), "mov": (True, 8), "h264": (True, 8),
                   "avi-grey": (False, 8), "ffv1-grey8": (False, 8)}


@pytest.mark.parametrize("case", sorted(OPENCV_CONTRACT))
def test_opencv_reader_contract(tmp_path, case):
    """Without PyAV, videos are read through OpenCV: the same contract, and the same pixels as PyAV's reader."""
    fmt = case.split("-")[0]
    _skip_without_writer(fmt)
    rgb, depth = OPENCV_CONTRACT[case]
    cfg = SynthConfig(n_frames=N, width_px=WIDTH, height_px=HEIGHT, fps=FPS, rgb=rgb, bit_depth=depth, seed=4)
    movie = synthesize(cfg, tmp_path, fmt=fmt).movie
    truth = np.stack(list(Renderer(cfg).frames()))
    with OpenCVVideoMovie(movie) as m, open_movie(movie) as ref:
        assert m.info.format.startswith("video-opencv:") and m.info.warnings == ()
        check_contract(m, truth, FPS, FORMATS[fmt].lossless, np.random.default_rng(1))
        for k, (a, b) in enumerate(zip(m.frames(), ref.frames(), strict=True)):
            np.testing.assert_array_equal(a, b, err_msg=f"frame {k}")
        idx, sample = m.sample(8)
        for k, frame in zip(idx, sample, strict=True):
            np.testing.assert_array_equal(frame, truth[k] if FORMATS[fmt].lossless else ref.read(int(k)))


def test_opencv_reader_says_when_it_reads_fewer_bits(tmp_path):
    """16-bit colour FFV1 through OpenCV comes out as 8 bits: said in the movie's warnings, with the fix."""
    cfg = SynthConfig(n_frames=6, width_px=WIDTH, height_px=HEIGHT, rgb=True, bit_depth=16, seed=2)
    movie = synthesize(cfg, tmp_path, fmt="ffv1").movie
    truth = np.stack(list(Renderer(cfg).frames()))
    with OpenCVVideoMovie(movie) as m:
        assert m.info.dtype == "uint8" and m.info.bit_depth == 8 and m.info.channels == 3
        assert len(m.info.warnings) == 1 and of_code(m.info, "movie.deep_read_shallow") == list(m.info.warnings)
        assert 'pip install "grainplug[video]"' in m.info.warnings[0]
        frame = m.read(3)
        np.testing.assert_allclose(frame, truth[3] / 257.0, atol=1.5)  # 8 bits (FFmpeg dithers a little)


@pytest.mark.parametrize("fmt", ["avi", "ffv1"])
def test_opencv_reader_refuses_a_truncated_video(tmp_path, fmt):
    """A raw AVI or an FFV1 Matroska cut in the middle: counted (``verify``, and always for Matroska, whose
    frame count is an estimate from its duration) it is refused when opened, else when read."""
    movie = synthesize(SynthConfig(n_frames=40, width_px=WIDTH, height_px=HEIGHT, seed=3), tmp_path, fmt=fmt).movie
    data = movie.read_bytes()
    movie.write_bytes(data[: len(data) // 2])
    with pytest.raises(MovieError, match="truncated"):
        OpenCVVideoMovie(movie, verify=True)
    try:
        m = OpenCVVideoMovie(movie)
    except MovieError as exc:  # the header's index is gone with the end of the file
        assert "copy" in str(exc) or "corrupt" in str(exc) or "complete" in str(exc)
        return
    with m, pytest.raises(MovieError, match="truncated"):
        list(m.frames())


@pytest.mark.parametrize("name", ["movie.ts", "misnamed.mp4"])
def test_opencv_reader_finds_frames_in_a_transport_stream(tmp_path, name):
    """MPEG-TS (camcorders' .ts/.mts), where OpenCV's seek lands on another frame: ``read(k)`` and
    ``frames(start)`` still give frame k (a .ts is decoded forward; under a name that promises an index,
    the seek is tried and caught by the frame's time stamp)."""
    from fractions import Fraction

    _skip_without_writer("h264")
    # 300 frames: OpenCV's seek in a stream this long lands ~1 s in, whatever frame is asked for
    frames = list(Renderer(SynthConfig(n_frames=300, width_px=WIDTH, height_px=HEIGHT, seed=8)).frames())
    path = tmp_path / name
    with av.open(str(path), "w", format="mpegts") as out:
        stream = out.add_stream("libx264", rate=Fraction(250))
        stream.width, stream.height, stream.pix_fmt = WIDTH, HEIGHT, "yuv420p"
        for f in frames:
            for packet in stream.encode(av.VideoFrame.from_ndarray(f, format="rgb24")):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    with OpenCVVideoMovie(path) as m:
        every = list(m.frames())
        assert len(every) == 300
        for k in (40, 3, 299, 0, 41):
            np.testing.assert_array_equal(m.read(k), every[k], err_msg=f"frame {k}")
        for a, b in zip(m.frames(100, 120, 4), every[100:120:4], strict=True):
            np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("kind", ["uint8 rgb", "uint16 grey", "float32 grey", "uint8 rgba"])
def test_array_movie_contract(kind):
    rng = np.random.default_rng(2)
    dtype, layout = kind.split()
    shape = {"rgb": (N, 48, 40, 3), "grey": (N, 48, 40), "rgba": (N, 48, 40, 4)}[layout]
    frames = (rng.uniform(0, 1000, shape).astype(dtype) if dtype == "float32"
              else rng.integers(0, np.iinfo(dtype).max, shape, endpoint=True, dtype=dtype))
    with open_movie(frames, fps=FPS) as m:
        assert m.info.channels == (1 if layout == "grey" else 3)
        check_contract(m, frames[..., :3] if layout == "rgba" else frames, FPS, True, rng)


@pytest.mark.parametrize("rgb", [True, False])
def test_compressed_video_is_decoded(tmp_path, rgb):
    """FFV1 (8-bit, packed BGR or grey): frames decoded exactly, bands from the decoded frames."""
    cfg = SynthConfig(n_frames=20, width_px=WIDTH, height_px=HEIGHT, rgb=rgb, seed=6)
    movie = synthesize(cfg, tmp_path, fmt="ffv1").movie
    truth = np.stack(list(Renderer(cfg).frames()))
    with open_movie(movie) as m:
        assert m.info.format.endswith("ffv1")
        check_contract(m, truth, FPS, True, np.random.default_rng(3))


@pytest.mark.parametrize("fmt", ["avi", "ffv1", "h264", "mjpeg"])
def test_video_read_seeks_to_the_frame(tmp_path, fmt):
    """``read(k)`` reaches frame k, for intra-only and inter-coded video, with the packets
    counted when opened (``verify``) or not (the frame rate gives the time)."""
    _skip_without_writer(fmt)
    movie = synthesize(SynthConfig(n_frames=60, width_px=WIDTH, height_px=HEIGHT, seed=3), tmp_path, fmt=fmt).movie
    with open_movie(movie, verify=True) as m:
        every = list(m.frames())
        assert len(every) == 60
        for k in (59, 1, 17, 33):
            np.testing.assert_array_equal(m.read(k), every[k], err_msg=f"frame {k}")
    with open_movie(movie) as m:
        for k in (41, 2):
            np.testing.assert_array_equal(m.read(k), every[k], err_msg=f"frame {k}")


@pytest.mark.parametrize(("fmt", "width", "rgb"), [("avi", 128, True), ("avi", 127, True), ("avi", 126, False),
                                                   ("mov", 128, True)])
def test_raw_video_read_straight_from_the_file(tmp_path, fmt, width, rgb):
    """Raw video (odd widths with padded rows, grey, AVI and MOV): frames, sample and bands
    equal PyAV's own decoding, frame times those of the frame rate."""
    cfg = SynthConfig(n_frames=40, width_px=width, height_px=HEIGHT, rgb=rgb, seed=6)
    movie = synthesize(cfg, tmp_path, fmt=fmt).movie
    with av.open(str(movie)) as container:
        decoded = [f.to_ndarray(format="rgb24" if rgb else "gray") for f in container.decode(video=0)]
    truth = list(Renderer(cfg).frames())
    for a, b in zip(decoded, truth, strict=True):  # the reference is right
        np.testing.assert_array_equal(a, b)
    with open_movie(movie) as m:
        idx, sample = m.sample(16)
        assert len(idx) == 16
        for k, frame in zip(idx, sample, strict=True):
            assert frame.flags.c_contiguous
            np.testing.assert_array_equal(frame, decoded[k])
        np.testing.assert_allclose(m.timestamps_s(), np.arange(40) / FPS, atol=1e-9)
        check_band(m, decoded, np.random.default_rng(5))
        for a, b in zip(m.frames(), decoded, strict=True):
            np.testing.assert_array_equal(a, b)


def _write_bottom_up_avi(path, frames, fps=250):
    """A minimal AVI written by hand (not by FFmpeg): 24-bit BGR DIB rows stored bottom-up,
    padded to 4 bytes, an idx1 index — the layout of many cameras' uncompressed AVIs."""

    def chunk(fourcc, data):
        return fourcc + struct.pack("<I", len(data)) + data + (b"\0" if len(data) % 2 else b"")

    n, h, w, _ = frames.shape
    line = (w * 3 + 3) // 4 * 4
    size = line * h
    avih = struct.pack("<14I", int(1e6 / fps), size * fps, 0, 0x10, n, 0, 1, size, w, h, 0, 0, 0, 0)
    strh = struct.pack("<4s4sIHHIIIIIIIIhhhh", b"vids", b"DIB ", 0, 0, 0, 0, 1, fps, 0, n, size,
                       0xFFFFFFFF, 0, 0, 0, w, h)
    strf = struct.pack("<IiiHHIIiiII", 40, w, h, 1, 24, 0, size, 0, 0, 0, 0)  # height > 0: bottom-up
    strl = chunk(b"LIST", b"strl" + chunk(b"strh", strh) + chunk(b"strf", strf))
    hdrl = chunk(b"LIST", b"hdrl" + chunk(b"avih", avih) + strl)
    movi, idx, off = [], [], 4
    for f in frames:
        rows = np.zeros((h, line), np.uint8)
        rows[:, : w * 3] = f[::-1, :, ::-1].reshape(h, w * 3)
        c = chunk(b"00db", rows.tobytes())
        idx.append(struct.pack("<4sIII", b"00db", 0x10, off, size))
        movi.append(c)
        off += len(c)
    body = b"AVI " + hdrl + chunk(b"LIST", b"movi" + b"".join(movi)) + chunk(b"idx1", b"".join(idx))
    path.write_bytes(b"RIFF" + struct.pack("<I", len(body)) + body)


def test_bottom_up_avi_written_by_other_means(tmp_path, rng):
    """Rows stored bottom-up, BGR, padded: frames, samples and bands come out the right
    way up, as from the same frames in memory."""
    frames = rng.integers(0, 256, (12, 20, 30, 3), dtype=np.uint8)  # 30 px: rows padded to 92 bytes
    path = tmp_path / "bu.avi"
    _write_bottom_up_avi(path, frames)
    with open_movie(path) as m:
        check_contract(m, frames, FPS, True, np.random.default_rng(8))
        idx, sample = m.sample(5)
        np.testing.assert_array_equal(np.stack(sample), frames[idx])
    band = random_band(np.random.default_rng(9), (20, 30))
    with open_movie(path) as m, open_movie(frames, fps=FPS) as a:  # channels summed in another order
        np.testing.assert_allclose(m.read_band(band, threads=2), a.read_band(band, threads=2), rtol=1e-6)


@pytest.mark.parametrize(("codec", "pix_fmt"), [("utvideo", "gbrp"), ("ffvhuff", "gbrp"), ("ffv1", "bgr0")])
def test_lossless_rgb_video_written_by_other_means(tmp_path, rng, codec, pix_fmt):
    """Lossless RGB video as other software writes it (planar or packed): frames decoded
    exactly, and bands the plain profiles of those frames, of all three channels."""
    if codec not in av.codecs_available:
        pytest.skip(f"this FFmpeg has no {codec} encoder")
    frames = rng.integers(0, 256, (10, 32, 48, 3), dtype=np.uint8)
    path = tmp_path / f"{codec}.avi"
    with av.open(str(path), "w") as container:
        stream = container.add_stream(codec, rate=250)
        stream.width, stream.height, stream.pix_fmt = 48, 32, pix_fmt
        for k, f in enumerate(frames):
            vf = av.VideoFrame.from_ndarray(f, format="rgb24")
            vf.pts = k
            for packet in stream.encode(vf):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)
    with open_movie(path) as m:
        check_contract(m, frames, FPS, True, np.random.default_rng(10))


def test_tiff_stacks_beyond_4_gb_are_written_as_bigtiff(tmp_path, rng):
    frames = rng.integers(0, 256, (3, 64, 48, 3), dtype=np.uint8)
    for n_frames, big in ((3, False), (2_000_000, True)):  # 2e6 frames of 9 kB: 18 GB announced
        path = tmp_path / f"m{n_frames}.tif"
        with MovieWriter(path, "tiff", fps=FPS, n_frames=n_frames) as w:
            for f in frames:
                w.write(f)
        with tifffile.TiffFile(path) as tif:
            assert tif.is_bigtiff is big
        with open_movie(path) as m:
            check_contract(m, frames, FPS, True, np.random.default_rng(n_frames))


def test_read_file_and_sparse_maps_give_the_file_bytes(tmp_path, rng):
    data = rng.integers(0, 2**16, 50_000, dtype=np.uint16)
    path = tmp_path / "x.raw"
    path.write_bytes(b"hdr" + data.tobytes())
    for random_access in (False, True):
        np.testing.assert_array_equal(read_file(path, 3 + 2 * 100, (10, 30), np.uint16, random_access=random_access),
                                      data[100:400].reshape(10, 30))
    for sparse in (False, True):  # offsets off the page grid, shapes of several axes
        got = map_file(path, 3 + 2 * 5000, (20, 1000), np.uint16, sparse=sparse)
        np.testing.assert_array_equal(got, data[5000:25000].reshape(20, 1000))
        got = map_file(path, 3 + 2 * 49_000, (10, 4, 25), np.uint16, sparse=sparse)
        np.testing.assert_array_equal(got, data[49_000:].reshape(10, 4, 25))
    with pytest.raises(MovieError, match="truncated"):
        read_file(path, 3 + 2 * 49_990, (20,), np.uint16)


@pytest.mark.parametrize("fmt", ["tiff", "avi", "mraw", "cine", "seq"])
def test_a_given_frame_rate_that_contradicts_the_file_is_said(tmp_path, fmt):
    """A slip of the user's --fps (25 for 250) is used (the user decides) but said; the file's own rate, or
    one within 1 % of it, is not."""
    movie = synthesize(SynthConfig(n_frames=8, width_px=WIDTH, height_px=HEIGHT, fps=FPS, rgb=fmt in ("tiff", "avi"),
                                   seed=1), tmp_path, fmt=fmt).movie
    with open_movie(movie, fps=25.0) as m:
        assert m.info.fps == 25.0 and m.info.fps_source == "user"
        said = of_code(m.info, "movie.fps_disagrees")
        assert len(said) == 1 and "given (25 fps)" in said[0] and "records (250 fps)" in said[0], m.info.warnings
        assert "fps=" in said[0]
    for fps in (None, FPS, FPS * 1.005):
        with open_movie(movie, fps=fps) as m:
            assert "movie.fps_disagrees" not in codes(m.info), m.info.warnings
