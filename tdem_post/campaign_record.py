"""The campaign's result as records (issue 26): :class:`CaseRow`, one case's row (a row of
``results.csv`` and of report.md's table), and :class:`CampaignRecord`, the fits over pressure
and the table, stored as ``campaign.json`` beside report.md. results.csv, report.md and case 12 of
docs/validation.md are written from, or read from, these records (tdem_post.records: one
serializer, one reader that refuses a missing or unknown field). Its home is the results layer,
below both ``tdem.campaign`` (which writes it) and case 12 of ``validation`` (which reads it).

A field declares its CSV column and, with ``md``, its column in report.md's table; a field named
as a key of the case's summary takes its value. Adding a per-case quantity: a field of
:class:`~tdem_post.post_run.PostSummary` and its value in ``PostResult.record()``
(tdem_post/post_run.py), and the same field here (3 edits in 2 files).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from tdem_post.fits import PowerFit
from tdem_post.post_run import MEAN_FIELD_LAWS, PostSummary
from tdem_post.records import column

NAN = float("nan")
# the mean fields report.md's ratio line and the gamma(p) figure compare with gamma: the two
# contact formulas (pipe's is in the table); every name comes from MEAN_FIELD_LAWS
COMPARED_MEAN_FIELDS = tuple(law for law in MEAN_FIELD_LAWS if law != "pipe")
RECORD = "campaign.json"        # the campaign's record, beside report.md


def _md(place, heading, fmt=None, *, name=None):
    """A report column: the field's value in ``fmt`` (or the cell function ``fmt``)."""
    def cell(r):
        return fmt(r) if callable(fmt) else format(getattr(r, name), fmt or "")
    return column(md=(place, heading, cell))


def _row_fields() -> list:
    """CaseRow's fields in results.csv's column order: (name, type, dataclasses.field)."""
    def f(name, tp, place=None, heading=None, fmt=None, **kw):
        md = _md(place, heading, fmt, name=name) if heading else column(**kw)
        return (name, tp, field(metadata=md))
    return [
        ("seed", "int | None", field(default=None, metadata=column(
            md=(0, "seed", lambda r: str(r.seed)), optional=True))),
        f("pressure_pa", float, 1, "p (bar)", lambda r: f"{r.pressure_pa / 1e5:.3g}"),
        f("pressure_target_pa", float),     # the series' nominal pressure (packing's name)
        f("law", str, 2, "law", "s"),
        f("n_particles", int),
        f("mean_coordination", float, 3, "Z", ".2f"),
        f("solid_fraction", float, 4, "φ", ".4f"),
        f("mean_normal_force_n", float, 5, "mean F_n (N)", ".3g"),
        f("gamma", float, 6, "γ", ".4g"),
        f("gamma_ci95_low", float, 7, "95 % CI",
          lambda r: f"{r.gamma_ci95_low:.4g}–{r.gamma_ci95_high:.4g}"),
        f("gamma_ci95_high", float),
        f("gamma_residual_rms_k", float),
        # 003's convention: alpha = gamma_paper k_p / (rho_p c_p), post's reading of its fitted
        # diffusivity (gamma rho_p c_p over the run's own bed capacity)
        f("gamma_paper", float, 8, "γ_paper", ".4g"),
        f("gamma_steady", float, 9, "γ_steady", ".4g"),
        # fabric-tensor (affine) estimate k_zz / k_p: an upper bound of gamma_steady (Thomson)
        f("gamma_affine", float, 10, "γ_aff", ".4g"),
        f("gamma_affine_transverse", float),
        f("fabric_nz2", float, 11, "⟨n_z²⟩", ".4f"),
        f("fabric_nz2_conductance", float),
        f("contact_stress_axial_pa", float),
        f("tau_s", float, 13, "τ (s)", ".4g"),
        f("tau_series_s", float),
        f("tau_slab_s", float, 14, "τ_slab (s)", ".4g"),
        f("length_m", float),
        *(f(f"gamma_mean_field_{law}", float, 12 + k / 100, f"γ_mf {law}", ".4g")
          for k, law in enumerate(MEAN_FIELD_LAWS)),
        f("thermal_wall_seconds", float),
        f("case_wall_seconds", float),
        # the run's thermal.h5 flags ("none": clean; see docs/solvers.md)
        f("flags", str, 15, "flags", "s"),
        # post's own (e.g. gamma_model_form) and what it could not measure, with why
        f("post_flags", str),
        f("not_measurable", str),
    ]


def _optional():
    return field(default=None, metadata=column(optional=True))


@dataclass(frozen=True, kw_only=True)
class CaseSummary(PostSummary):
    """A campaign case's post/summary.json: post's :class:`PostSummary` and what the campaign
    adds (absent from a summary written by ``tdem post``, or before they were recorded)."""
    case_wall_seconds: float | None = _optional()       # thermal run and post
    thermal_wall_seconds: float | None = _optional()
    scene_sha256: str | None = _optional()      # tdem.campaign.scene_sha256 of the case's scene
    packing_sha256: str | None = _optional()    # of the packing file's bytes
    post_sha256: str | None = _optional()       # of the tdem_post code that posted it


def _from_summary(cls, summary: CaseSummary, pressure_target_pa: float,
                  seed: int | None = None):
    """A case's row from its summary and the series' nominal pressure: a field named as one
    of the summary's is its value (post's None, "not measurable", is NaN); the others are
    derived here (:data:`_DERIVED`)."""
    def get(key, k=None):
        v = getattr(summary, key)
        if v is not None and k is not None:
            v = v[k]
        return NAN if v is None else v
    derived = dict(
        seed=seed, pressure_target_pa=float(pressure_target_pa),
        gamma_ci95_low=get("gamma_ci95", 0), gamma_ci95_high=get("gamma_ci95", 1),
        **{f"gamma_mean_field_{law}": get("gamma_mean_field", law) for law in MEAN_FIELD_LAWS},
        flags=summary.flags or "none",      # the run's thermal.h5 flags, "none" when clean
        not_measurable="; ".join(f"{k}: {v}" for k, v in summary.not_measurable.items()))
    return cls(**{f.name: derived[f.name] if f.name in derived else get(f.name)
                  for f in dataclasses.fields(cls)})


_DERIVED = {"seed", "pressure_target_pa", "gamma_ci95_low", "gamma_ci95_high", "flags",
            "not_measurable", *(f"gamma_mean_field_{law}" for law in MEAN_FIELD_LAWS)}


# one case (pressure x law [x seed]) of a campaign: a row of results.csv and of report.md
CaseRow = dataclasses.make_dataclass(
    "CaseRow", _row_fields(), frozen=True, kw_only=True,
    namespace={"__module__": __name__, "from_summary": classmethod(_from_summary),
               "__doc__": "One case (pressure x law [x seed]): a row of results.csv and of "
                          "report.md's table; NaN where post found a value not measurable."})


# every other field of a row is a summary's key (a misspelt field fails here, at import)
_unknown = {f.name for f in dataclasses.fields(CaseRow)} - _DERIVED \
    - {f.name for f in dataclasses.fields(CaseSummary)}
if _unknown:
    raise TypeError(f"CaseRow fields neither derived nor a summary's: {sorted(_unknown)}")


@dataclass(frozen=True)
class LawFits:
    """One law's fits over pressure (of one seed's series), p in bar."""
    law: str
    seed: int | None
    gamma: PowerFit | None       # gamma = a p^b + c (None: fewer than 4 distinct pressures)
    tau_s: PowerFit | None       # tau = a p^b + c, a and c in s
    gamma_loglog_slope: float | None     # None: fewer than 2 distinct pressures measured
    gamma_paper_over_paper: tuple[float, ...]    # gamma_paper / 003's gamma(p), low to high p


@dataclass(frozen=True)
class CampaignRecord:
    """A campaign's result: its cases' rows and the fits over pressure; campaign.json."""
    campaign: str                # the campaign file's name
    laws: tuple[str, ...]
    seeds: tuple[int, ...] | None
    wall_seconds: float
    paper_gamma: dict[str, float]    # 003 Fig. 7: a, b, c of gamma = a p^b + c (p in bar)
    paper_tau_s: dict[str, float]    # 003 Fig. 10: a, b, c of tau = a p^b + c (s, p in bar)
    fits: tuple[LawFits, ...]
    rows: tuple[CaseRow, ...]

    def fits_of(self, law: str, seed: int | None = None) -> LawFits:
        for f in self.fits:
            if f.law == law and f.seed == seed:
                return f
        raise KeyError(f"no fits of law {law!r}" + (f", seed {seed}" if seed is not None
                                                    else ""))
