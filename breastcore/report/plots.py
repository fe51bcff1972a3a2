"""Figures of the report: shapes, identification history, sensitivity heatmap (matplotlib, Agg)."""

from __future__ import annotations

import numpy as np
from matplotlib.colors import SymLogNorm
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, MaxNLocator

from breastcore.inverse.uncertainty import at_limit
from breastcore.model.parameters import IDENTIFIED

_LABELS = {"R": "R", "H": "H", "lambda_breast": "λ", "mu_breast": "μ", "lambda_skin": "λ_s", "mu_skin": "μ_s"}


def subplots(*args, figsize, **kwargs):
    """``matplotlib.pyplot.subplots`` without pyplot: no global backend or figure registry to change."""
    fig = Figure(figsize=figsize)
    return fig, fig.subplots(*args, **kwargs)


def _save(fig, path):
    """Write ``fig`` to ``path`` and return it (for tests to read its artists)."""
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return fig


def _gravity(ds, posture):
    """The posture's gravity direction: a solution's ``gravity``, else ``(0, sin θ, −cos θ)`` from
    ``posture_angle`` (an identification's), else None."""
    if "gravity" in ds:
        return ds["gravity"].sel(posture=posture).values
    if "posture_angle" in ds:
        theta = np.radians(float(ds["posture_angle"].sel(posture=posture)))
        return np.array([0.0, np.sin(theta), -np.cos(theta)])
    return None


def shape_figure(ds, posture, path):
    """Side (y–z) and front (x–z) views of the skin, gravity-free (grey) and deformed (colour), mm,
    with the torso plane y = 0 (side view), the lowest point of the fixed infra-mammary fold (dashed)
    and the direction of gravity, so that a reader sees where the breast hangs against its fold."""
    x0 = ds["reference_position"].values * 1e3
    x = ds["position"].sel(posture=posture).values * 1e3
    tris = ds["skin_triangles"].values
    g = _gravity(ds, posture)
    fold_low = x0[ds["fold"].values.astype(bool), 2].min() if "fold" in ds else None
    fig, axes = subplots(1, 2, figsize=(8, 4))
    for ax, (i, j, label) in zip(axes, [(1, 2, "side: y anterior (mm)"), (0, 2, "front: x lateral (mm)")]):
        ax.triplot(x0[:, i], x0[:, j], tris, color="0.8", lw=0.4)
        ax.triplot(x[:, i], x[:, j], tris, color="tab:red", lw=0.5)
        ax.set_xlabel(label)
        ax.set_ylabel("z superior (mm)")
        ax.set_aspect("equal")
        if i == 1:
            ax.axvline(0, color="k", lw=1)
        if fold_low is not None:
            ax.axhline(fold_low, color="0.3", lw=0.8, ls="--")
            ax.annotate("fold", xy=(0.02, fold_low), xycoords=("axes fraction", "data"), xytext=(0, 2),
                        textcoords="offset points", fontsize=7, color="0.3")
    if g is not None and np.linalg.norm(g) > 0:           # gravity direction in the side view
        d = 0.12 * g[1:] / np.linalg.norm(g)
        axes[0].annotate("g", xy=(0.85 + d[0], 0.85 + d[1]), xytext=(0.85, 0.85), xycoords="axes fraction",
                         arrowprops={"arrowstyle": "->"})
    fig.suptitle(f"{posture}: gravity-free (grey) and equilibrium (red)")
    return _save(fig, path)


def convergence_figure(identifications, path, labels=None):
    """Parameter / truth (or / final) and cost against iteration: colour per parameter, line
    style and marker per run (``labels``, in the cost panel's legend)."""
    fig, axes = subplots(1, 2, figsize=(9, 4))
    styles = ["-", "--", ":", "-."]
    markers = ["o", "s", "^", "v", "D", "x"]
    hidden = set()
    for k, ds in enumerate(identifications):
        ref = ds["truth"].values if "truth" in ds else ds["estimate"].values
        rel = ds["parameters"].values / ref - 1
        # an estimate that is a limit (→ 0, → ∞) is no final value to measure a distance to
        limit = ds["limit"].values if "limit" in ds and "truth" not in ds else np.zeros(len(IDENTIFIED))
        style = {"linestyle": styles[k % len(styles)], "marker": markers[k % len(markers)], "markersize": 3}
        for j, name in enumerate(IDENTIFIED):
            if limit[j]:
                hidden.update(at_limit([_LABELS[name]], [limit[j]]))
                continue
            axes[0].plot(ds["iteration"], rel[:, j] * 100, color=f"C{j}", alpha=0.7,
                         label=_LABELS[name] if k == 0 else None, **style)
        run = labels[k] if labels is not None and k < len(labels) else f"run {k + 1}"
        axes[1].semilogy(ds["iteration"], np.maximum(ds["cost"].values, 1e-30), color="k", alpha=0.6, label=run,
                         **style)
    if len(identifications) > 1:
        axes[1].legend(fontsize=7, title="run", title_fontsize=7)
    for ax in axes:                              # iterations are whole numbers
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    axes[0].set_xlabel("iteration")
    if hidden:
        axes[0].text(0.02, 0.02, "not shown, limits: " + ", ".join(sorted(hidden)), transform=axes[0].transAxes,
                     fontsize=7)
    # symmetric log: a modulus 100× off and one 1 % off in one panel (linear within ±1 %)
    axes[0].set_yscale("symlog", linthresh=1.0)
    axes[0].set_ylabel(("parameter error" if "truth" in identifications[0] else "distance to final")
                       + " (%, symmetric log scale)")
    axes[0].legend(ncol=3, fontsize=8)
    axes[1].set_xlabel("iteration")
    axes[1].set_ylabel("cost E")
    return _save(fig, path)


def sensitivity_figure(ds, path):
    """Heatmaps of the relative sensitivity ∂lnΛ/∂ln m (linearised, and finite if present)."""
    names = [n for n in ("linearised", "finite") if n in ds]
    fig, axes = subplots(1, len(names), figsize=(6 * len(names), 5), squeeze=False)
    for ax, name in zip(axes[0], names):
        S = ds[name].values.T
        lim = max(np.nanmax(np.abs(S)), 1.0)
        # symmetric log: one loose modulus (±350 % per %) washed out every other column on a linear scale
        im = ax.imshow(S, cmap="RdBu_r", norm=SymLogNorm(linthresh=1.0, vmin=-lim, vmax=lim, base=10),
                       aspect="auto")
        ax.set_xticks(range(len(IDENTIFIED)), [_LABELS[p] for p in IDENTIFIED])
        ax.set_yticks(range(S.shape[0]), ds["measurement"].values, fontsize=7)
        ax.set_title(f"{name}: relative sensitivity")
        ax.set_xlabel("identified parameter")
        fig.colorbar(im, ax=ax, label="∂ln Λ_j / ∂ln m_i (% per %; symmetric log, linear within ±1)")
    return _save(fig, path)


def error_vs_runtime_figure(summary, path):
    """Log–log mean parameter error and measurement residual against wall time, per method and mesh."""
    fig, axes = subplots(1, 2, figsize=(9, 4.5))
    methods = list(dict.fromkeys(summary["method"].values))
    error = np.abs(summary["relative_error"].values).mean(axis=1) * 100
    for k, method in enumerate(methods):
        sel = summary["method"].values == method
        t = summary["wall_time"].values[sel]
        for ax, y in zip(axes, (error[sel], summary["measurement_residual"].values[sel] * 100)):
            ax.loglog(t, np.maximum(y, 1e-12), "o", color=f"C{k}", label=method)
            for ti, yi, mesh in zip(t, y, summary["mesh"].values[sel]):
                ax.annotate(str(mesh), (ti, max(yi, 1e-12)), fontsize=7, xytext=(4, 4 - 10 * k),   # one row
                            textcoords="offset points", annotation_clip=False, color=f"C{k}")       # per method
    axes[0].set_ylabel("mean |parameter error| (%)")
    axes[1].set_ylabel("RMS measurement residual (%)")
    for ax in axes:
        ax.set_xlabel("identification wall time (s)")
        ax.grid(True, which="both", alpha=0.3)
        ax.margins(x=0.15, y=0.15)                      # room for the mesh labels beside the points
        for axis, (low, high) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):   # 34, not 3.4×10¹
            axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
            within_a_decade = high < 10 * low                                  # no major tick: label minor ones
            axis.set_minor_formatter(FuncFormatter(lambda v, _, on=within_a_decade: f"{v:.3g}" if on else ""))
    axes[0].legend(fontsize=8)
    _save(fig, path)


def stability_map(ds, path):
    """Convergence rate for pairs of factors (a convergence map), one panel per pair."""
    pairs = [("lam_over_mu", "mu"), ("mu_s", "c"), ("H_over_R", "delta")]
    fig, axes = subplots(1, len(pairs), figsize=(5 * len(pairs), 4))
    converged = ds["outcome"].values == "converged"
    for ax, (a, b) in zip(axes, pairs):
        va, vb = sorted(set(ds[a].values.tolist())), sorted(set(ds[b].values.tolist()))
        rate = np.full((len(vb), len(va)), np.nan)
        for i, y in enumerate(vb):
            for j, x in enumerate(va):
                sel = (ds[a].values == x) & (ds[b].values == y)
                if sel.any():
                    rate[i, j] = converged[sel].mean()
        im = ax.imshow(rate, vmin=0, vmax=1, cmap="RdYlGn", origin="lower")
        ax.set_xticks(range(len(va)), [f"{v:g}" for v in va])
        ax.set_yticks(range(len(vb)), [f"{v:g}" for v in vb])
        ax.set_xlabel(a)
        ax.set_ylabel(b)
    fig.colorbar(im, ax=list(axes), label="fraction converged")
    fig.savefig(path, dpi=110)
