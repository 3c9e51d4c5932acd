"""The model's commands: stability, simulate, resonance (loaded only when one of them is named)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from .._version import __version__
from ..errors import ParameterError
from ..simulation.state import SimulationParams
from ..stability.params import ModelParams
from .common import (
    OVERWRITE_HELP,
    PUBLICATION_HELP,
    default_of,
    echo_json,
    err_console,
    figure_options_of,
    in_flags,
    refuse_existing,
    say_warning,
)
from .types import FINITE, Number

if TYPE_CHECKING:
    pass


# ---------------------------------------------------------------------------
def _m(name: str) -> object:
    """:class:`ModelParams`' default of ``name`` (the model's options take theirs from there)."""
    return default_of(ModelParams, name)


#: the set-up of the paper's model (each default the paper as printed), shared by stability and simulate
_MODEL_OPTIONS = [
    click.option("--diameter-mm", type=FINITE, default=_m("diameter_mm"), show_default=True,
              help="Pipe inner diameter D."),
    click.option("--grain-diameter-um", type=FINITE, default=_m("grain_diameter_um"), show_default=True,
              help="Grain diameter d."),
    click.option("--c0", type=FINITE, default=_m("c0"), show_default=True, help="Base-state compactness."),
    click.option("--kappa", type=FINITE, default=_m("kappa"), show_default=True, help="Janssen coefficient."),
    click.option("--mu-s", type=FINITE, default=_m("mu_s"), show_default=f"{_m('mu_s'):.4f}",
              help="Friction coefficient (tan 32°)."),
    click.option("--theta-deg", type=FINITE, default=_m("theta_deg"), show_default=True,
              help="Pipe inclination from vertical."),
    click.option("--gamma", type=FINITE, default=_m("gamma"), show_default=True,
              help="Ratio of specific heats of air."),
    click.option("--air-viscosity-pa-s", type=FINITE, default=_m("air_viscosity_pa_s"), show_default=True),
    click.option("--grain-density-kg-m3", type=FINITE, default=_m("grain_density_kg_m3"), show_default=True),
    click.option("--b", "b", type=FINITE, default=_m("b"), show_default=True, help="Capillary factor on friction."),
    click.option("--B1-star", "b1_star", type=FINITE, default=None,
              help="Use this B1* instead of computing it from D, d, c0, gamma, mu_a, rho_s."),
    click.option("--variant", type=click.Choice(["printed", "frozen-friction"]), default=_m("variant"),
              show_default=True,
              help="printed: the paper's equations as printed; frozen-friction: wall friction not perturbed "
                   "(= --friction-law coulomb-frozen)."),
    click.option("--friction-law", type=click.Choice(["v2", "v|v|", "coulomb-frozen", "coulomb-weight",
                                                     "coulomb-janssen"]), default=None,
              metavar="LAW",
              help="Wall friction F(c, v), one of: v2 as printed (2 b mu_s v^2), v|v| (signed), coulomb-frozen "
                   "(held at its base value), coulomb-weight (following the local weight), coulomb-janssen "
                   "(rate-independent Coulomb friction on the contact stress, needs --jamming; issue 37) [default: "
                   "v2, or the variant's]."),
    click.option("--friction-v-eps", type=Number(1e-9, 1e3, unit="v_c"), default=None,
              help="coulomb-janssen only: regularise the friction as tanh(v / v_eps), v_eps in units of v_c "
                   "[default: exact, set-valued Coulomb friction that holds a jammed column at rest]."),
    click.option("--wall-stress", type=click.Choice(["local", "janssen-column"]), default=_m("wall_stress"),
              show_default=True,
              help="coulomb-janssen only: the friction's normal stress, each cell's own contact stress (local) or "
                   "Janssen's stress carried down each dense stretch, zero at its top and at its free bottom "
                   "(janssen-column; exact friction only)."),
    click.option("--mu-static-over-kinetic", type=Number(1.0, 1e3), default=_m("mu_static_over_kinetic"),
              show_default=True,
              help="Exact Coulomb laws only: static over kinetic wall friction (>= 1; --mu-s is then the kinetic "
                   "coefficient): a cell at rest stays while the force on it is below this times the friction "
                   "(stick-slip; issue 37)."),
    click.option("--drag", type=click.Choice(["carman-kozeny", "stokes-carman"]), default=_m("drag"),
              show_default=True,
              help="Air-grain drag: Carman-Kozeny as in the paper, or Stokes' single-grain drag added "
                   "(stokes-carman: finite per grain in dilute regions)."),
    click.option("--janssen-v2-term/--no-janssen-v2-term", "janssen_v2_term", default=_m("janssen_v2_term"),
              show_default=True,
              help="Keep the paper's Janssen term (v / kappa) v_z in the grains' momentum (as printed), or drop it "
                   "(issue 37's closure)."),
    click.option("--base-pressure", "base_pressure", default="printed", show_default=True,
              metavar="printed|atmospheric|PA",
              help="Absolute air pressure of the base state: as printed (P* = 1, i.e. rho_s g D = 74 Pa), the "
                   "atmosphere (101325 Pa), or a value in Pa; B1* and the compressibility term follow it."),
    click.option("--base-velocity", type=click.Choice(["printed", "balanced"]), default=_m("base_velocity"),
              show_default=True,
              help="printed: v* = 1; balanced: the velocity at which wall friction carries the weight."),
    click.option("--jamming", is_flag=True,
              help="Add a jamming pressure Fr (c - c_min)^2 / (c_max - c)^5 (Johnson & Jackson) to the grains' "
                   "momentum: it diverges at random close packing (not in the paper)."),
    click.option("--jamming-fr-pa", type=Number(0, 1e6, unit="Pa"), default=_m("jamming_fr_pa"), show_default=True,
              help="Its constant Fr."),
    click.option("--jamming-c-min", type=Number(0.0, 0.99), default=_m("jamming_c_min"), show_default=True,
              help="Its c_min, where contacts start to last (random loose packing for coulomb-janssen, 0.55-0.58)."),
    click.option("--jamming-c-max", type=Number(0.01, 0.99), default=_m("jamming_c_max"), show_default=True,
              help="Its random close packing c_max."),
]


def _model_options(f):
    for option in reversed(_MODEL_OPTIONS):
        f = option(f)
    return f


def _model_params(diameter_mm: float, grain_diameter_um: float, c0: float, kappa: float, mu_s: float,
                  theta_deg: float, gamma: float, air_viscosity_pa_s: float, grain_density_kg_m3: float,
                  b: float, b1_star: float | None, variant: str, friction_law: str | None, base_pressure: str,
                  base_velocity: str, jamming: bool, jamming_fr_pa: float, jamming_c_max: float,
                  jamming_c_min: float = 0.50, friction_v_eps: float | None = None, wall_stress: str = "local",
                  drag: str = "carman-kozeny", janssen_v2_term: bool = True, mu_static_over_kinetic: float = 1.0):
    """The :class:`ModelParams` of the model options."""
    from ..stability import P_ATM_PA, ModelParams

    if base_pressure == "printed":
        base_pressure_pa = None
    elif base_pressure == "atmospheric":
        base_pressure_pa = P_ATM_PA
    else:
        try:
            base_pressure_pa = float(base_pressure)
        except ValueError:
            raise ParameterError(f"--base-pressure must be printed, atmospheric or a pressure in Pa, "
                                 f"got {base_pressure!r}") from None
    return ModelParams(diameter_mm=diameter_mm, grain_diameter_um=grain_diameter_um, c0=c0, kappa=kappa,
                       mu_s=mu_s, theta_deg=theta_deg, gamma=gamma, air_viscosity_pa_s=air_viscosity_pa_s,
                       grain_density_kg_m3=grain_density_kg_m3, b=b, B1_star_override=b1_star, variant=variant,
                       friction_law=friction_law, base_pressure_pa=base_pressure_pa, base_velocity=base_velocity,
                       jamming=jamming, jamming_fr_pa=jamming_fr_pa, jamming_c_max=jamming_c_max,
                       jamming_c_min=jamming_c_min, friction_v_eps=friction_v_eps, wall_stress=wall_stress, drag=drag,
                       janssen_v2_term=janssen_v2_term, mu_static_over_kinetic=mu_static_over_kinetic)


@click.command()
@_model_options
@click.option("--k-min", type=Number(1e-6, 1e4), default=0.001, show_default=True,
              help="Smallest wavenumber, dimensionless (k* = k D; wavelength lambda/D = 2 pi / k*).")
@click.option("--k-max", type=Number(1e-6, 1e4), default=3.0, show_default=True, help="Largest wavenumber k*.")
@click.option("--n-k", type=Number(10, 1e12, unit="wavenumbers", integer=True), default=1000, show_default=True,
              help="How many wavenumbers, evenly spread from --k-min to --k-max (at least 10; solved in chunks with "
                   "flat memory, 10^8 in minutes; refused when estimated over an hour). Beyond 10^5, --json and "
                   "--plot hold a curve of 10^4 of them that keeps the peak and the cut-offs.")
@click.option("--json", "as_json", is_flag=True, help="Print roots, most unstable mode, cut-offs and inputs as JSON.")
@click.option("--plot", "plot", type=click.Path(path_type=Path), default=None,
              help="Write the paper's Fig. 9 (growth rates against k*) to this PNG (with --sweep: lambda/D).")
@click.option("--sweep", "sweep_spec", default=None, metavar="NAME=START:STOP:N",
              help="Vary one input (e.g. grain_diameter_um=50:400:15 or c0=0.45:0.62:10) and report "
                   "the most unstable and cut-off wavelengths for each value.")
def stability(k_min: float, k_max: float, n_k: int, as_json: bool, plot: Path | None, sweep_spec: str | None,
              **model: object) -> None:
    """Linear stability of the paper's 1D model: the three roots omega*(k*).

    Every set-up choice is a switch whose default is the paper as printed: the friction law,
    the base pressure and the base velocity; the output states the base state's residual,
    its absolute pressure and the caveats of the set-up.
    """
    from ..stability import analyze_stability

    p = _model_params(**model)
    variant, base_pressure, base_velocity, jamming = (model["variant"], model["base_pressure"],
                                                      model["base_velocity"], model["jamming"])
    if not (0 < k_min < k_max) or n_k < 10:
        raise ParameterError("need 0 < --k-min < --k-max and --n-k >= 10")
    if plot is not None and plot.suffix.lower() not in (".png", ".svg", ".pdf"):
        raise ParameterError(f"--plot must name a .png, .svg or .pdf file, got {plot.name}")
    if sweep_spec:
        _stability_sweep(p, sweep_spec, k_min=k_min, k_max=k_max, n_k=n_k, as_json=as_json, plot=plot)
        return
    res = analyze_stability(p, k_min=k_min, k_max=k_max, n_k=n_k)
    if plot is not None:
        import matplotlib.pyplot as plt

        from ..plotting.stability import plot_growth_rates

        fig = plot_growth_rates(res)
        _save_figure(fig, plot)
        plt.close(fig)
    if as_json:
        _print_stability_warnings(res.warnings)
        echo_json({"grainplug_version": __version__, **res.as_dict()})
        return
    m = res.most_unstable
    click.echo(f"variant            {variant}" + ("" if p.is_printed else
                                                      f"   (set-up: friction {p.law}, base pressure "
                                                      f"{base_pressure}, base velocity {base_velocity}"
                                                      + (", jamming pressure" if jamming else "") + ")"))
    click.echo(f"B1*                {p.B1_star:.6g}   (P_c = {p.P_c_pa:.4g} Pa, t_c = {p.t_c_s:.4g} s, "
               f"v_c = {p.v_c_m_s:.4g} m/s)")
    click.echo(f"base state         c0 = {p.c0:g}, v0* = {p.v0_star:.4g} ({p.v0_star * p.v_c_m_s:.3g} m/s), "
               f"P0 = {p.base_pressure_abs_pa:.4g} Pa (P0* = {p.P0_star:.4g}; B* = B1* P0* = {p.B_star:.4g})")
    click.echo(f"base-state balance -c0 cos(theta) + F(c0, v0) = {p.base_state_residual:+.4f} "
               "(0 if the base state were steady)")
    for line in p.caveats():
        click.echo(f"caveat             {in_flags(line)}")
    if m is None:
        click.echo(f"most unstable      none: every k* in [{k_min:g}, {k_max:g}] is stable")
        if p.is_printed:
            click.echo("note               the printed model does not give the paper's long-wave instability "
                       "(k* ~ 0.2, cut-off ~ 0.6); --variant frozen-friction does — see docs/stability.md")
    else:
        label = "most unstable     " if m.at_range_edge is None else "largest in range  "
        click.echo(f"{label} k* = {m.k:.5f}  growth rate {m.growth_rate:.5f}/t_c "
                   f"({m.growth_rate / p.t_c_s:.3g}/s)  phase speed {m.phase_speed:+.4f} v_c "
                   f"({m.phase_speed * p.v_c_m_s:+.3f} m/s)  lambda/D = {m.wavelength_over_diameter:.3f}"
                   + ("" if m.at_range_edge is None else f"  (at {m.at_range_edge}: no maximum inside the range)"))
    for kc in res.cutoff_k:
        click.echo(f"cut-off            k* = {kc:.5f}  lambda/D = {2 * 3.141592653589793 / kc:.3f}")
    if plot is not None:
        click.echo(f"figure             {plot}")
    _print_stability_warnings(res.warnings)


def _s(name: str) -> object:
    """:class:`SimulationParams`' default of ``name``."""
    return default_of(SimulationParams, name)


def _print_stability_warnings(lines: list[str]) -> None:
    """The analysis' warnings, its keywords named as this command's flags (k_min=: --k-min)."""
    for line in lines:
        say_warning(line)


@click.command()
@_model_options
@click.option("--boundary", type=click.Choice(["periodic", "open"]), default=_s("boundary"), show_default=True,
              help="periodic: a box that repeats (the linear analysis' set-up); open: a pipe fed at the top, "
                   "the base pressure held at both ends, free outflow at the bottom.")
@click.option("--length-D", "length_D", type=Number(1, 1e6, unit="D"), default=_s("length_D"), show_default=True,
              help="Box or pipe length in pipe diameters.")
@click.option("--cells", "n_cells", type=Number(16, 1e6, unit="cells", integer=True), default=_s("n_cells"),
              show_default=True, help="Finite-volume cells.")
@click.option("--duration-tc", type=Number(1e-3, 1e7, unit="t_c"), default=_s("duration_tc"), show_default=True,
              help="Simulated time in units of t_c = sqrt(D/g).")
@click.option("--output-interval-tc", type=Number(1e-4, 1e7, unit="t_c"), default=_s("output_interval_tc"),
              show_default=True,
              help="Time between saved fields.")
@click.option("--cfl", type=Number(0.01, 0.5), default=_s("cfl"), show_default=True,
              help="Courant number of each Runge-Kutta stage (a step is 3 stages long).")
@click.option("--noise", type=Number(0, 0.099), default=_s("noise"), show_default=True,
              help="Standard deviation of the initial compactness noise.")
@click.option("--seed", type=Number(0, 2**32 - 1, integer=True), default=0, show_default=True,
              help="Seed of the initial noise.")
@click.option("--feed-c", type=Number(0.001, 0.999), default=None, help="Open pipe: compactness fed at the top "
              "[default: c0].")
@click.option("--feed-v", type=Number(1e-6, 1e3, unit="v_c"), default=None,
              help="Open pipe: velocity of the fed grains in units of v_c [default: the base velocity].")
@click.option("--feed-rate-g-s", type=Number(1e-6, 1e6, unit="g/s"), default=None,
              help="Open pipe: mass flow rate of the grains fed at the top (sets their velocity).")
@click.option("--inlet-seal-D", "inlet_seal_D", type=Number(0, 1e6, unit="D"), default=None,
              help="Open pipe: the air enters the top only through a column of this many D of the fed grains (a "
                   "hopper full of grains), the atmosphere beyond it [default: the pressure held at the top face].")
@click.option("--balance/--no-balance", "balance", default=None,
              help="Add the uniform force S that makes the base state steady, as the linear analysis assumes "
                   "[default: in a periodic box, not in an open pipe].")
@click.option("--out", "out_dir", type=click.Path(path_type=Path), required=True,
              help="Folder for fields.nc, summary.json and diagram.png (replaced as a whole).")
@click.option("--publication", is_flag=True, help=PUBLICATION_HELP)
@click.option("--overwrite", is_flag=True, help=OVERWRITE_HELP)
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def simulate(boundary: str, length_D: float, n_cells: int, duration_tc: float, output_interval_tc: float, cfl: float,
             noise: float, seed: int, feed_c: float | None, feed_v: float | None, feed_rate_g_s: float | None,
             inlet_seal_D: float | None, balance: bool | None, out_dir: Path, publication: bool, overwrite: bool,
             as_json: bool, **model: object) -> None:
    """Integrate the paper's 1D model in time (finite volumes) and measure what it forms.

    Conservative in grain and air mass (the air's mass balance replaces the printed
    pressure equation, to which it linearises). The compactness diagram goes through
    the same plug detection and measures as a movie, beside the linear prediction and
    the waves measured on the fields. See docs/model.md.
    """
    import numpy as np

    from ..simulation import run_study

    p = _model_params(**model)
    sim = SimulationParams(boundary=boundary, length_D=length_D, n_cells=n_cells, duration_tc=duration_tc,
                           output_interval_tc=output_interval_tc, cfl=cfl, noise=noise, feed_c=feed_c, feed_v=feed_v,
                           feed_rate_g_s=feed_rate_g_s, balance=balance, inlet_seal_D=inlet_seal_D)
    from .._atomic import check_output_place

    check_output_place(out_dir, kind="simulation")  # refuse a bad place before the run, not after
    refuse_existing(out_dir, overwrite)
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed:.0f}/{task.total:g} t_c"),
                  TimeRemainingColumn(), console=err_console, transient=True,
                  disable=not err_console.is_terminal) as bar:
        # the compiled kernel is built on the first run after an install (~15 s), before the first output
        first = "simulating (compiles once after install, ~15 s)"
        task = bar.add_task(first, total=duration_tc)
        study = run_study(p, sim, rng=np.random.default_rng(seed), seed=seed,
                          progress=lambda t, total: bar.update(task, completed=t, description="simulating"))
    study.save(out_dir, figure_options=figure_options_of(None, None, publication, None))
    summary = study.summary
    if as_json:
        echo_json(summary)
        return
    for line in simulation_lines(summary):
        click.echo(line)
    click.echo(f"outputs            {out_dir}/ (fields.nc, summary.json, diagram.png)")


def simulation_lines(summary: dict) -> list[str]:
    """The terminal report of ``grainplug simulate``."""
    r, w, m, lin = summary["run"], summary["waves"], summary["measured_as_movie"], summary["linear"]
    out = [f"run                {r['boundary']} {r['length_D']:g} D, {r['n_cells']} cells, {r['duration_tc']:g} t_c "
           f"({r['duration_s']:.3g} s) in {r['n_steps']} steps, {r['wall_s']:.1f} s",
           f"conservation       grain {r['grain_drift']:.1e}, air {r['air_drift']:.1e} (relative change)"
           if r["boundary"] == "periodic" else
           # the ends let grains and air in and out: the content's change is no check of the scheme, the grain's
           # budget (change = inflow - outflow) is
           f"content change     grain {r['grain_drift']:.1e}, air {r['air_drift']:.1e} (relative; the pipe's ends "
           "let grains and air in and out)"]
    if r["boundary"] != "periodic" and "grain_budget_residual" in r:
        g0 = abs(r["grain_total"][0]) or 1.0
        out.append(f"grain budget       in {r['grain_inflow'] / g0:.3f}, out {r['grain_outflow'] / g0:.3f} (of the "
                   f"starting content); change - (in - out) = {r['grain_budget_residual']:.1e}")
    if r.get("balance_force_rho_s_g"):
        out.append(f"balance force      S = {r['balance_force_rho_s_g']:+.3f} rho_s g, uniform, so that the base state "
                   "is steady (--no-balance leaves it out)")
    if lin["most_unstable_lambda_D"] is None:
        out.append("linear theory      stable: no wavelength grows")
        if summary.get("model", {}).get("printed_setup"):
            out.append("note               the printed model is stable, so no waves are expected; --variant "
                       "frozen-friction gives the paper's long-wave instability (docs/model.md)")
    else:
        edge = lin.get("most_unstable_at_range_edge")
        what = "most unstable" if not edge else f"largest growth (at {edge} of k* in [0.001, 3]: no maximum inside),"
        out.append(f"linear theory      {what} lambda/D = {lin['most_unstable_lambda_D']:.1f}, growth "
                   f"{lin['growth_rate_per_tc']:.4f}/t_c, phase speed {lin['phase_speed_m_s']:+.3f} m/s")
    if w["n_waves"]:
        fronts = w["front_speed_m_s"]
        fronts = "not followed" if fronts is None or fronts != fronts else f"{fronts:+.3f} m/s"  # NaN: not followed
        out.append(f"waves at the end   {w['n_waves']} in the box, dense segment {w['dense_length_D']:.1f} D "
                   f"({w['dense_fraction']:.2f} of the box), fronts {fronts}, "
                   f"c {w['c_min']:.3f}..{w['c_max']:.3f}")
    else:
        out.append(f"waves at the end   none: {w.get('why_none') or 'the flow stayed uniform'}")
    if m["regime"] == "none":
        out.append(f"as a movie         {in_flags(m['statement'])}")
        if w["n_waves"]:
            out.append(f"                   (c stays within {w['c_min']:.2f}..{w['c_max']:.2f}: no air bubble forms, "
                       "so a camera would see a compact flow)")
    else:
        cel = "-" if m["celerity_m_s"] is None else f"{m['celerity_m_s']:+.3f} m/s"
        plug = "-" if m["plug_length_mm"] is None else f"{m['plug_length_mm']:.1f} mm"
        bub = "-" if m["bubble_length_mm"] is None else f"{m['bubble_length_mm']:.1f} mm"
        out.append(f"as a movie         {m['regime']}: celerity {cel}, plugs {plug}, bubbles {bub}")
    for warning in summary["warnings"]:
        out.append(f"warning            {in_flags(warning)}")
    return out


_SWEEP_NAMES = {"B1_star": "B1_star_override", "B1-star": "B1_star_override"}


#: a sweep longer than this is announced (with its estimate), seconds
LONG_SWEEP_S = 60.0

#: axis labels of the inputs a sweep varies
SWEEP_LABELS = {"diameter_mm": "pipe diameter D (mm)", "grain_diameter_um": "grain diameter d (µm)",
                "grain_density_kg_m3": "grain density ρs (kg/m³)", "air_viscosity_pa_s": "air viscosity (Pa s)",
                "gamma": "ratio of specific heats γ", "g_m_s2": "gravity g (m/s²)", "c0": "compactness c0",
                "kappa": "Janssen coefficient κ", "mu_s": "friction coefficient μs", "theta_deg": "inclination θ (°)",
                "b": "capillary factor b", "B1_star_override": "B1*", "base_pressure_pa": "base pressure P0 (Pa)",
                "jamming_fr_pa": "jamming constant Fr (Pa)", "jamming_c_min": "jamming c_min",
                "jamming_c_max": "jamming c_max"}


def _stability_sweep(p, spec: str, *, k_min: float, k_max: float, n_k: int, as_json: bool,
                     plot: Path | None) -> None:
    """``--sweep NAME=START:STOP:N``: lambda/D of the most unstable mode and of the cut-offs."""
    import dataclasses

    import numpy as np

    from ..stability import ModelParams, sweep
    from ..stability.analysis import _duration, check_sweep_size

    try:
        name, rng = spec.split("=", 1)
        start, stop, count = rng.split(":")
        first, last, n = float(start), float(stop), float(count)
        if not (np.isfinite(first) and np.isfinite(last) and n >= 1 and n == int(n)):
            raise ValueError
    except (ValueError, OverflowError):
        raise ParameterError(f"--sweep {spec!r}: write NAME=START:STOP:N (N a whole number >= 1), "
                             "e.g. c0=0.45:0.62:10") from None
    name = _SWEEP_NAMES.get(name.strip(), name.strip().replace("-", "_"))
    fields = {f.name for f in dataclasses.fields(ModelParams)} - {"variant"}
    if name not in fields:
        raise ParameterError(f"--sweep: unknown input {name!r}; choose one of {', '.join(sorted(fields))}")
    check_sweep_size(int(n), param="sweep")  # before the values are made
    values = np.linspace(first, last, int(n))
    told: list[float] = []

    def tell(seconds: float) -> None:  # a long sweep is said once, with its estimate (Ctrl-C stops it)
        if seconds > LONG_SWEEP_S and not told:
            told.append(seconds)
            err_console.print(f"note: {int(n):,} values, about {_duration(seconds)} (Ctrl-C stops it)",
                              highlight=False, soft_wrap=True)

    try:
        rows = sweep(p, name, values, k_min=k_min, k_max=k_max, n_k=n_k, on_estimate=tell)
    except ParameterError as exc:  # the sweep's values are this option's
        if exc.param != "values":
            raise
        raise ParameterError(exc.message, param="sweep") from None
    if plot is not None:
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6.4, 4.4), constrained_layout=True)
        x = [r[name] for r in rows]
        ax.plot(x, [r["most_unstable_wavelength_over_diameter"] or np.nan for r in rows], "o-",
                label="most unstable λ/D")
        ax.plot(x, [(r["cutoff_wavelength_over_diameter"] or [np.nan])[0] for r in rows], "s--",
                label="cut-off λ/D")
        ax.set_xlabel(SWEEP_LABELS.get(name, name))
        ax.set_ylabel("λ/D")
        ax.set_title(f"variant '{p.variant}'", fontsize=9)
        ax.legend(fontsize=8)
        _save_figure(fig, plot)
        plt.close(fig)
    edge = [f"{r[name]:g}" for r in rows if r.get("most_unstable_at_range_edge")]
    if edge:
        err_console.print(f"[yellow]warning:[/] for {name} = {', '.join(edge)} the growth rate is largest at an end of "
                          f"the k* range: its k* max is that end, not a maximum — widen --k-min/--k-max",
                          highlight=False, soft_wrap=True)
    if as_json:
        echo_json({"grainplug_version": __version__, "variant": p.variant, "input": name, "rows": rows,
                    "inputs": p.as_dict()})
        return
    click.echo(f"{name:>18s} {'B1*':>8s} {'k* max':>8s} {'λ/D max':>8s} {'cut-off k*':>10s} {'λ/D cut':>8s}")
    for r in rows:
        km, lm = r["most_unstable_k"], r["most_unstable_wavelength_over_diameter"]
        kc = r["cutoff_k"][0] if r["cutoff_k"] else None
        lc = r["cutoff_wavelength_over_diameter"][0] if r["cutoff_k"] else None

        def f(v, nd=4):
            return f"{v:.{nd}f}" if v is not None else "stable"

        click.echo(f"{r[name]:18.5g} {r['B1_star']:8.4f} {f(km):>8s} {f(lm, 2):>8s} {f(kc):>10s} {f(lc, 2):>8s}")


def _save_figure(fig, path: Path) -> None:
    """Save a figure atomically."""
    from .._atomic import atomic_file

    with atomic_file(path) as tmp:
        fig.savefig(tmp, dpi=120, format=path.suffix.lstrip(".") or "png")


@click.command()
@click.option("--compactness", type=FINITE, default=0.55, show_default=True, help="Grain volume fraction c.")
@click.option("--grain-density-kg-m3", type=FINITE, default=_m("grain_density_kg_m3"), show_default=True)
@click.option("--grain-sound-speed-m-s", type=FINITE, default=5000.0, show_default=True)
@click.option("--pressure-pa", type=FINITE, default=101325.0, show_default=True)
@click.option("--temperature-k", type=FINITE, default=293.15, show_default=True)
@click.option("--gamma", type=FINITE, default=_m("gamma"), show_default=True)
@click.option("--isothermal", is_flag=True, help="Isothermal air (default: adiabatic).")
@click.option("--column-length-m", type=FINITE, default=1.0, show_default=True, help="Length of the grain-air column.")
@click.option("--plug-length-m", type=FINITE, default=0.03, show_default=True)
@click.option("--air-column-m", type=FINITE, default=1.0, show_default=True,
              help="Length of the air column under the plug (the spring).")
@click.option("--json", "as_json", is_flag=True, help="Print the inputs, sound speeds and modes as JSON.")
def resonance(as_json: bool, **kwargs: object) -> None:
    """Acoustic resonance of the grain-air column (Wood's sound speed, pipe modes, plug on air spring)."""
    from ..stability.resonance import ResonanceInputs
    from ..stability.resonance import resonance as compute

    r = compute(ResonanceInputs(**kwargs))
    if as_json:
        echo_json({"grainplug_version": __version__, **r})
        return
    click.echo(f"air             {r['process']}, sound speed {r['air_sound_speed_m_s']:.1f} m/s, "
               f"density {r['air_density_kg_m3']:.3f} kg/m3")
    click.echo(f"mixture (Wood)  sound speed {r['mixture_sound_speed_m_s']:.2f} m/s, "
               f"density {r['mixture_density_kg_m3']:.1f} kg/m3")
    click.echo("half-wave       " + ", ".join(f"{f:.2f}" for f in r["half_wave_hz"]) + " Hz")
    click.echo("quarter-wave    " + ", ".join(f"{f:.2f}" for f in r["quarter_wave_hz"]) + " Hz")
    spring = r["plug_on_air_spring_hz"]
    click.echo(f"plug on spring  {'none (no grains)' if spring is None else f'{spring:.2f} Hz'}")
