"""Planting drift: the planted rows wander smoothly off the lines the planter logged.

A planter steered by GNSS plants its rows where the guidance put it, not exactly on the lines
its log (and the farm's map) holds: the guidance's tracking error and, without RTK, the
receiver's own drift move each pass sideways (docs/localisation.md "Rows off the map"). Here
each planter pass — ``drift_pass_rows`` adjacent rows planted together — gets one lateral
offset along the row,

    d(t) = A · Σₖ wₖ sin(2π k t / λ + φₖ) / Σₖ wₖ,   k = 1, 2, 3,  wₖ = 1/k,

with A ``drift_amplitude``, λ ``drift_wavelength`` and the phases φₖ drawn per pass from the
scenario's ``drift`` stream: smooth (its shortest wavelength λ/3), never beyond A, and the same
for the same seed. The plants of a pass move with it; weeds do not; the ``RowFrame`` (and so
the route and every export of the rows) stays the logged lines. A plant moved out of the field
is dropped, as the layout drops jittered ones. Off by default (A = 0): nothing is drawn and the
layout is returned as it is.

Where the rows were planted is known to the benchmark, not to the robot: ``lane_error`` measures
a pose from the planted lane's centre (midway between its two drifted rows), the error a
follower of the rows is judged by where the route is only the logged line.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from .arrays import BoolArray, FloatArray, IntArray
from .layout import Layout, RowFrame
from .spec import LayoutSpec

HARMONICS = 3


def pass_of(row: IntArray, rows_per_pass: int) -> IntArray:
    """The planter pass of each row index (rows counted across the field, ascending)."""
    return np.asarray(row, np.int64) // rows_per_pass


def drift_phases(n_rows: int, spec: LayoutSpec, rng: np.random.Generator) -> FloatArray:
    """(passes, HARMONICS) phases, one row per planter pass."""
    passes = (n_rows + spec.drift_pass_rows - 1) // spec.drift_pass_rows
    return rng.uniform(0.0, 2.0 * math.pi, (max(passes, 0), HARMONICS))


def drift_offset(t: FloatArray, phases: FloatArray, spec: LayoutSpec) -> FloatArray:
    """Lateral offset (m, along ``RowFrame.n``) at along-row positions ``t`` of passes whose
    phases are ``phases`` (one row of phases per entry of ``t``)."""
    k = np.arange(1, HARMONICS + 1, dtype=np.float64)
    w = 1.0 / k
    arg = 2.0 * math.pi * np.asarray(t, np.float64)[:, None] * k / spec.drift_wavelength + phases
    return spec.drift_amplitude * (np.sin(arg) @ w) / w.sum()


def apply_drift(
    lay: Layout, spec: LayoutSpec, field: BaseGeometry, rng: np.random.Generator
) -> Layout:
    """``lay`` with every crop plant moved by its pass's drift (weeds stay)."""
    if spec.drift_amplitude <= 0.0:
        return lay
    rows: RowFrame = lay.rows
    phases = drift_phases(len(rows.offsets), spec, rng)
    crop = ~lay.is_weed
    t, s = rows.to_rows(lay.x[crop], lay.y[crop])
    p = pass_of(lay.row[crop], spec.drift_pass_rows)
    s = s + drift_offset(t, phases[p], spec)
    x, y = lay.x.copy(), lay.y.copy()
    x[crop], y[crop] = rows.to_enu(t, s)
    keep = ~crop | shapely.contains_xy(field, x, y)
    return dataclasses.replace(
        lay, x=x[keep], y=y[keep], row=lay.row[keep], is_weed=lay.is_weed[keep]
    )


def planted_offset(
    rows: RowFrame, phases: FloatArray, spec: LayoutSpec, row: IntArray, t: FloatArray
) -> FloatArray:
    """Where rows ``row`` were planted at along-row positions ``t``: each one's logged offset
    along ``RowFrame.n`` plus its pass's drift (``phases`` as ``drift_phases`` drew them)."""
    row = np.asarray(row, np.int64)
    base = np.asarray(rows.offsets, np.float64)[row]
    if spec.drift_amplitude <= 0.0 or len(row) == 0:
        return base
    return base + drift_offset(t, phases[pass_of(row, spec.drift_pass_rows)], spec)


def lane_error(
    rows: RowFrame, phases: FloatArray, spec: LayoutSpec, x: FloatArray, y: FloatArray
) -> tuple[FloatArray, BoolArray]:
    """(error, in_lane) of ENU points: the signed offset (m, along ``RowFrame.n``) of each
    from the centre of the lane it stands in as planted, midway between the lane's two rows
    with their drift, and whether it stands in a planted lane (between two adjacent logged
    rows, along the row where both are planted). Outside a lane the error is NaN."""
    t, s = rows.to_rows(np.asarray(x, np.float64), np.asarray(y, np.float64))
    t, s = np.atleast_1d(t), np.atleast_1d(s)
    offsets = np.asarray(rows.offsets, np.float64)
    lane = np.searchsorted(offsets, s, side="right") - 1
    inside = (lane >= 0) & (lane < len(offsets) - 1)
    assert rows.seg_row is not None and rows.seg_t is not None
    seg_row, seg_t = np.asarray(rows.seg_row), np.asarray(rows.seg_t, np.float64)

    def planted(r: IntArray) -> BoolArray:
        on = (
            (seg_row[None, :] == r[:, None])
            & (seg_t[None, :, 0] <= t[:, None])
            & (t[:, None] <= seg_t[None, :, 1])
        )
        return on.any(axis=1)

    k = np.where(inside, lane, 0)
    inside &= planted(k) & planted(k + 1)
    err = np.full(len(t), np.nan)
    if inside.any():
        ti, ki = t[inside], k[inside]
        centre = 0.5 * (
            planted_offset(rows, phases, spec, ki, ti)
            + planted_offset(rows, phases, spec, ki + 1, ti)
        )
        err[inside] = s[inside] - centre
    return err, inside
