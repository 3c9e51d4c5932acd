"""Acoustic resonance estimates against hand computations."""

from __future__ import annotations

import json
import math

import pytest

from grainplug.errors import ParameterError
from grainplug.stability.resonance import ResonanceInputs, mixture_sound_speed, resonance


def test_pure_air_limit():
    m = mixture_sound_speed(ResonanceInputs(compactness=0.0))
    assert m["mixture_sound_speed_m_s"] == pytest.approx(m["air_sound_speed_m_s"])
    # no grains, no plug on the air spring (a 1e-12 kg stand-in gave 6.9 MHz)
    assert resonance(ResonanceInputs(compactness=0.0))["plug_on_air_spring_hz"] is None
    assert m["air_sound_speed_m_s"] == pytest.approx(math.sqrt(1.4 * 287.05 * 293.15), rel=1e-9)


def test_wood_relation_by_hand():
    c, rho_s, a_s, P, T = 0.55, 2500.0, 5000.0, 101325.0, 293.15
    rho_a = P / (287.05 * T)
    a_a2 = 1.4 * P / rho_a
    rho_m = c * rho_s + (1 - c) * rho_a
    a_m = 1 / math.sqrt(rho_m * (c / (rho_s * a_s**2) + (1 - c) / (rho_a * a_a2)))
    r = resonance(ResonanceInputs())
    assert r["mixture_sound_speed_m_s"] == pytest.approx(a_m, rel=1e-12)
    # "a few m/s": far below the air's own
    assert 10 < a_m < 20
    assert r["half_wave_hz"][0] == pytest.approx(a_m / 2)
    assert r["quarter_wave_hz"][0] == pytest.approx(a_m / 4)
    assert r["quarter_wave_hz"][1] == pytest.approx(3 * a_m / 4)


def test_isothermal_is_slower_by_sqrt_gamma():
    a = mixture_sound_speed(ResonanceInputs(isothermal=False, grain_sound_speed_m_s=1e12))
    b = mixture_sound_speed(ResonanceInputs(isothermal=True, grain_sound_speed_m_s=1e12))
    assert a["mixture_sound_speed_m_s"] / b["mixture_sound_speed_m_s"] == pytest.approx(math.sqrt(1.4), rel=1e-9)


def test_plug_on_spring_by_hand():
    r = resonance(ResonanceInputs(plug_length_m=0.03, air_column_m=0.5))
    f = math.sqrt(1.4 * 101325 / 0.5 / (2500 * 0.55 * 0.03)) / (2 * math.pi)
    assert r["plug_on_air_spring_hz"] == pytest.approx(f)


def test_bad_inputs_and_cli(capsys):
    with pytest.raises(ParameterError):
        ResonanceInputs(compactness=1.0)
    from grainplug.cli import main

    assert main(["resonance", "--json"]) == 0
    d = json.loads(capsys.readouterr()[0])
    assert {"mixture_sound_speed_m_s", "half_wave_hz", "quarter_wave_hz", "plug_on_air_spring_hz",
            "inputs"} <= set(d)
    assert main(["resonance", "--pressure-pa", "-1"]) == 2
