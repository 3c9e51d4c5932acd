"""Warnings with stable codes: each warning keeps its sentence and carries a code (``scale.tube_narrow``).

A :class:`CodedWarning` is a ``str`` (``res.warnings`` stays a list of sentences that print, compare and
serialise as before) with a ``.code``: what a program filters on (the campaign table's
``warning_codes`` column, a reviewer's corrections replacing their own warnings, the command line
naming its flags), while the sentence is for people and may be reworded. :data:`CODES` lists every
code with its meaning and fix; ``docs/analysis.md`` shows the same table (a test keeps them equal).

The codes are ``area.kind``: ``shake.*``, ``movie.*`` (what a file says of itself), ``window.*``, ``tube.*``,
``scale.*``, ``calibration.*``, ``light.*``, ``frames.*``, ``time.*``, ``flow.*``, ``plugs.*``, ``still.*``,
``compactness.*``, ``grains.*``, ``corrections.*``, ``manifest.*``. A warning read back from an older
``result.npz`` (saved as plain text) has the code ``legacy.uncoded``.
"""

from __future__ import annotations

from collections.abc import Iterable

#: code -> (what it means, what to do): every code a warning of an analysis can carry
CODES: dict[str, tuple[str, str]] = {
    # what the movie's file says of itself (readers)
    "movie.fps_disagrees": ("the frame rate given is not the one the file records",
                            "check the frame rate given (fps=) against the camera's settings"),
    "movie.fps_stamps": ("the file's time stamps and its header disagree on the frame rate",
                         "check how the file was saved; give fps= to time the frames by their number"),
    "movie.frames_out_of_step": ("some frames' time stamps are out of step with the others (dropped frames?)",
                                 "check the recording; the frames are timed by the rate"),
    "movie.deep_read_shallow": ("a video deeper than 8 bits is read as 8 bits",
                                "install the video extra (PyAV) or export the frames as 16-bit TIFF"),
    "movie.truncated": ("the file ends before its last frame; the whole frames are analysed",
                        "copy the file again"),
    "movie.header_levels": ("the camera file's black/white levels are out of range and ignored",
                            "check the camera's export settings"),
    "movie.extra_bytes": ("the camera file holds more bytes than its frames", "check the file is the one recorded"),
    "movie.other": ("something a camera file says of itself", "as the sentence says"),
    # the window of the movie analysed
    "window.end_past_movie": ("the window's end is past the movie's; analysed to the movie's end",
                              "check the end and its unit (frames or seconds)"),
    # the tube
    "tube.cut_by_frame": ("the tube's contents change at a side of the frame: the tube is cut by it",
                          "frame the whole tube and its walls, or give roi= around a whole tube"),
    "tube.second_region": ("the frames change as much elsewhere across the tube as in it (a second tube?)",
                           "give roi= around the tube to analyse"),
    "tube.walls_unseen": ("in back light, no tube wall was seen beside the moving contents (a droplet, a jet?)",
                          "check that a tube is in view, or give roi= around it"),
    # the scale
    "scale.given_vs_tube": ("the tube seen is far wider or narrower than the given scale makes its bore",
                            "check mm_per_px= and tube_diameter_mm=, and that what was found is the tube"),
    "scale.edges_only": ("the scale comes from the tube's edges in the mean image (nothing moved, or the tube is "
                         "cut): it may be off by any amount and the intervals do not carry it",
                         "take a calibration image or give mm_per_px="),
    "scale.contents_back_lit": ("the scale comes from the width of the contents of a back-lit tube, uncorrected "
                                "(the intervals carry the lamp's narrowing, up to 35 %)",
                                "take a calibration image or give mm_per_px="),
    "scale.contents_unchecked": ("the scale comes from the tube's inner width seen through its contents, "
                                 "not cross-checked", "give tube_outer_diameter_mm=, or a calibration"),
    "scale.model_alone": ("the scale comes from the tube model alone, not cross-checked",
                          "give tube_outer_diameter_mm=, or a calibration"),
    "scale.model_disagrees": ("the tube model's estimates of the bore disagree",
                              "check tube_diameter_mm=, tube_outer_diameter_mm= and glass_index=, or calibrate"),
    "scale.tube_narrow": ("the tube is too few pixels wide for a scale within a few per cent",
                          "take a calibration image or give mm_per_px="),
    "scale.tube_wide": ("the tube fills most of the frame's width: its walls may be out of view",
                        "frame the walls, take a calibration image or give mm_per_px="),
    "scale.tube_model": ("the tube model doubts its own estimate (stripes or silhouette)", "as the sentence says"),
    "scale.calibration_size": ("the calibration image is not the size of the movie's frames",
                               "check the camera, lens, focus and distance did not change"),
    "scale.calibration_vs_tube": ("the tube's bore and the calibration disagree on the scale",
                                  "check the pattern's plane and pitch, and the tube's diameter"),
    "scale.calibration_doubted": ("the calibration and the tube disagree by more than the tube's optics allow: "
                                  "one of them is wrong, and the intervals carry the disagreement",
                                  "check the figure the sentence names (the pattern's pitch and level, "
                                  "tube_diameter_mm=, that the image is of this set-up)"),
    "scale.calibration": ("the calibration image itself is doubtful (not flat, tilted, varying scale)",
                          "as the sentence says; take the calibration image again"),
    "scale.calibration_varies_along_tube": ("(older results only) the calibration's scale varied "
                                            "by more than 0.3 % along the tube, and one scale was used",
                                            "analyse again: positions are now mapped through the calibration"),
    # what a calibration image says of itself (grainplug calibrate)
    "calibration.lens_distortion": ("the lens distorts the calibration image (barrel or pincushion): fitted, and "
                                    "the scale corrected for it", "none needed; the analysis takes the scale "
                                    "where the tube is"),
    # light
    "light.background": ("the background (light calibration) leaves something doubtful", "as the sentence says"),
    "light.moving_shadow": ("a light moving along the tube (a passing shadow) was read on the contents and divided "
                            "out", "keep people and things from passing between the lamp and the tube"),
    "light.saturated": ("part of the tube's pixels are at the camera's top value",
                        "lower the exposure or the light"),
    # frames and time
    "frames.repaired": ("frames unlike their neighbours (flicker, dropped, blank) were bridged",
                        "check those frames in the movie"),
    "frames.tube_unseen": ("frames in which the tube is not in view (its walls not seen): not measured",
                           "check those frames in the movie (something in front of the tube, the camera moved)"),
    "time.uneven": ("the frames are not evenly spaced in time: the file's own stamps are used",
                    "check how the file was made, or give fps= to time the frames by their number"),
    # the flow's direction
    "flow.against_given": ("the grains falling through the bubbles move against the flow direction given",
                           "check flow_direction="),
    "flow.assumed": ("the grains falling through the bubbles give no direction: the flow direction is assumed",
                     "give flow_direction="),
    "flow.sign_assumed": ("the celerity's sign rests on a flow direction only assumed (gravity down)",
                          "give flow_direction= if the camera was not upright"),
    # plugs and their measures
    "plugs.near_min_length": ("many plugs are just over min_plug_mm: shorter ones are likely dropped",
                              "lower min_plug_mm="),
    "plugs.implausible_speed": ("the plugs or the falling grains move faster than grains can fall",
                                "check the frame rate (fps=) and the scale"),
    "plugs.frame_cadence": ("the plug edges move back and forth every few whole frames: the recording's cadence "
                            "(a codec's group of pictures), not read as an oscillation (or, uncompressed, "
                            "reported with this doubt)",
                            "record losslessly or at a higher quality; check the movie was never compressed"),
    "plugs.oscillation_no_interval": ("the oscillation is given without intervals or kind: refined, its frequency left "
                                      "the spectrum's peak", "film more periods"),
    # the camera's shake (the tube moving in the image)
    "shake.corrected": ("the camera shook; the diagram was held still against the tube",
                        "nothing: a plug motion at the shake's frequency is not reported as the plugs'"),
    "shake.along_unmeasured": ("the camera shook, and its motion along the tube could not be measured",
                               "steady the camera, or put a still mark beside the tube"),
    "shake.too_large": ("the camera moved the tube across farther than the diagram's band is from its walls",
                        "steady the camera"),
    # still objects over the tube
    "still.region": ("a stretch of the tube where nothing changes over the record (a clamp, a fitting, the end)",
                     "leave it out of the region analysed (roi=)"),
    "still.track": ("a track that stays put while the plugs move (a still object taken for a plug), left out of the "
                    "lengths", "if it is a plug, see grainplug review; or leave such things out with roi= or mask_mm="),
    # the grains' compactness
    "compactness.unmeasured": ("references were given, but the compactness cannot be read (front light)",
                               "film in back light (a lamp behind the tube)"),
    "compactness.lamp_unknown": ("the lamp could not be compared between the movie and the references",
                                 "keep the lamp and the exposure unchanged between them"),
    # the grains' velocity inside the plugs
    "grains.texture_weak": ("the grains' velocity inside the plugs is not given: too little of the packed grains' "
                            "texture correlates from frame to frame",
                            "light the grains so that their texture shows (back light, sharp focus), film longer"),
    "grains.texture_still": ("the plugs' texture did not move by a sample over the longest lag: grains at rest, or a "
                             "pattern fixed to the tube or the camera (a scratch, dust, a codec's blocks)",
                             "look at the plugs in the movie; clean the tube, film with less compression"),
    # the grains' mass flow rate
    "mass_flow.disagrees": ("a run's weighed mass flow rate is outside the interval of the one measured from its movie",
                            "check the frame rate, scale, bore, packed compactness and grain density given"),
    # a reviewer's corrections
    "corrections.not_applied": ("an edit of corrections.json could not be applied to this analysis",
                                "review the run again"),
    "corrections.unchecked": ("edits name tracks of an earlier analysis without where they were",
                              "check them in grainplug review"),
    # a campaign's manifest
    "manifest.column_unknown": ("a manifest's column looks like a known one misspelt: kept as metadata",
                                "name the column as grainplug knows it"),
    # read back from a result saved before codes
    "legacy.uncoded": ("a warning read from a result.npz written before warnings had codes",
                       "analyse the movie again for coded warnings"),
}


class CodedWarning(str):
    """A warning's sentence (a ``str``) with its stable :attr:`code` (one of :data:`CODES`).

    Examples
    --------
    >>> w = coded("scale.tube_narrow", "the tube is only 9.0 px wide ...")
    >>> w.code, w == "the tube is only 9.0 px wide ..."
    ('scale.tube_narrow', True)
    """

    code: str

    def __new__(cls, code: str, text: str) -> CodedWarning:
        if code not in CODES:
            raise ValueError(f"unknown warning code {code!r}: add it to grainplug.warning_codes.CODES")
        obj = super().__new__(cls, text)
        obj.code = code
        return obj

    def __reduce__(self) -> tuple[type, tuple[str, str]]:  # pickled with its code (figure worker, batch workers)
        return (CodedWarning, (self.code, str(self)))

    def __repr__(self) -> str:
        return f"CodedWarning({self.code!r}, {str(self)!r})"


def coded(code: str, text: str) -> CodedWarning:
    """``text`` as a warning with ``code`` (a warning already coded keeps its own code)."""
    return text if isinstance(text, CodedWarning) else CodedWarning(code, text)


def code_of(warning: str) -> str:
    """A warning's code: its own, or ``legacy.uncoded`` for plain text (a result saved before codes)."""
    return getattr(warning, "code", "legacy.uncoded")


def codes_of(warnings: Iterable[str]) -> list[str]:
    """The code of each warning, in order (``summary.json``'s ``warning_codes``)."""
    return [code_of(w) for w in warnings]


def all_coded(code: str, texts: Iterable[str]) -> list[str]:
    """Each of ``texts`` coded with ``code`` unless it has a code already."""
    return [coded(code, t) for t in texts]
