"""Mesh convergence of the forward model (issue #2): nipple displacement and
deformed volume per posture on successively finer meshes, their differences to
the finest level and the observed order of convergence.

The mesh size is ``h = N^(-1/3)`` (N nodes), relative to the coarse level. The
observed order ``p`` is the least-squares slope of ``log |q_level − q_finest|``
against ``log h`` over the levels other than the finest (so it is biased low when
the second-finest level is close to the finest). The levels are independent gmsh
meshes, not nested refinements, so the differences also carry mesh-to-mesh noise.

Usage::

    python -m breastcore.studies.mesh_convergence [--levels coarse medium thin reference fine10k]
    python -m breastcore.studies.mesh_convergence --quick     # without fine10k (``make bench``)

``--quick`` drops fine10k, so the finest level (the differences' reference) is
``reference`` (3,010 nodes).
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from breastcore.report.text_table import fmt, header, print_table

LEVELS = ["coarse", "medium", "thin", "reference", "fine10k"]



def fit_exponent(nodes, times) -> float:
    """Least-squares slope of ``log(time)`` against ``log(nodes)``."""
    x, y = np.log(np.asarray(nodes, float)), np.log(np.asarray(times, float))
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(x[ok], y[ok], 1)[0])

def deformed_volume(problem, x):
    """Mesh volume of the deformed tets, ``Σ_τ |τ| det F_τ`` (m³)."""
    return float(problem.bulk.volume @ problem.bulk.det_F(x))


def solve_level(level, postures):
    from breastcore.forward.model import ForwardModel
    from breastcore.model.geometry import cap_volume
    from breastcore.model.mesh import mesh_level
    from breastcore.model.parameters import Parameters
    mesh = mesh_level(level)
    model, params = ForwardModel(mesh), Parameters()
    nipple = mesh.landmarks["nipple"]
    out = {}
    for posture in postures:
        tic = time.perf_counter()
        sol = model.solve(params, posture)
        problem = model.problem(params, posture)
        u = sol.position[nipple] - problem.reference[nipple]
        out[posture.name] = dict(nodes=len(mesh.nodes), u=u, volume=deformed_volume(problem, sol.position),
                                 rest_volume=float(problem.bulk.volume.sum()), exact_volume=cap_volume(params.R, params.H),
                                 min_det_F=sol.min_det_F, iterations=sol.iterations, time=time.perf_counter() - tic)
        print(f"  {level} {posture.name}: {time.perf_counter() - tic:.1f} s, {sol.iterations} it", flush=True)
    return out


def observed_order(nodes, errors):
    """Slope of log(error) against log(h), h = N^(-1/3); NaN if fewer than two positive errors."""
    nodes, errors = np.asarray(nodes, float), np.asarray(errors, float)
    ok = errors > 0
    if ok.sum() < 2:
        return float("nan")
    return fit_exponent(nodes[ok] ** (-1.0 / 3.0), errors[ok])


def parse_args(argv=None):
    """The command line (``sys.argv[1:]`` if ``argv`` is None), with the defaults ``--quick`` implies."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", nargs="+", default=LEVELS)
    parser.add_argument("--quick", action="store_true", help="coarse, medium, thin, reference only (make bench)")
    args = parser.parse_args(argv)
    return args


def main(argv=None):
    args = parse_args(argv)
    header("Mesh convergence", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    from breastcore.model.postures import paper_postures
    levels = [lv for lv in args.levels if not (args.quick and lv == "fine10k")]
    postures = paper_postures()
    data = {level: solve_level(level, postures) for level in levels}
    finest = levels[-1]
    print()
    for posture in postures:
        name = posture.name
        ref = data[finest][name]
        rows, nodes, err_u, err_v = [], [], [], []
        for level in levels:
            d = data[level][name]
            du = float(np.linalg.norm(d["u"] - ref["u"]))
            dv = abs(d["volume"] - ref["volume"]) / ref["volume"]
            rows.append([level, d["nodes"], 1e3 * d["u"][1], 1e3 * d["u"][2], 1e3 * float(np.linalg.norm(d["u"])),
                         1e3 * du if level != finest else "—", 1e6 * d["volume"],
                         f"{100 * (d['volume'] / d['rest_volume'] - 1):+.3f} %", f"{100 * dv:.3f} %" if level != finest else "—",
                         d["min_det_F"]])
            if level != finest:
                nodes.append(d["nodes"])
                err_u.append(du)
                err_v.append(dv)
        print_table(["level", "nodes", "nipple u_y mm", "nipple u_z mm", "|u| mm", f"|u − u_{finest}| mm",
                     "deformed volume cm³", "vs own rest volume", f"vs {finest}", "min det F"], rows,
                    title=f"{name}")
        print(f"observed order in h = N^(-1/3) (vs {finest}, {len(nodes)} levels): nipple displacement "
              f"p = {fmt(observed_order(nodes, err_u))}, deformed volume p = {fmt(observed_order(nodes, err_v))}\n")
    d = data[finest][postures[0].name]
    print(f"rest volume of the {finest} mesh {1e6 * d['rest_volume']:.4f} cm³, exact cap volume "
          f"{1e6 * d['exact_volume']:.4f} cm³ (the chordal mesh volume converges as h²)")


if __name__ == "__main__":
    main()
