"""Figures of training runs (benchmark and trajectory figures live with their data)."""

from __future__ import annotations

from pathlib import Path


def learning_curve(history: list[dict[str, float]], path: Path, title: str) -> None:
    """Held-out return, cross-track RMSE (overall and in-furrow) and completion vs wall time."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    t = [h["minutes"] for h in history]
    fig = Figure(figsize=(10, 3.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots(1, 2)
    ax[0].plot(t, [h["return"] for h in history], "o-")
    ax[0].set_xlabel("training time (min, this machine)")
    ax[0].set_ylabel("eval return (validation seeds)")
    ax[1].plot(t, [h["rmse"] for h in history], "o-", color="tab:red", label="RMSE")
    ax[1].plot(
        t, [h["in_furrow_rmse"] for h in history], "^-", color="tab:purple", label="in-furrow"
    )
    ax[1].legend(loc="upper left", fontsize=8)
    ax[1].set_xlabel("training time (min)")
    ax[1].set_ylabel("cross-track RMSE (m)")
    ax2 = ax[1].twinx()
    ax2.plot(t, [h["completion"] for h in history], "s--", color="tab:green")
    ax2.set_ylabel("completion (%)", color="tab:green")
    fig.suptitle(title)
    fig.savefig(path, dpi=100)
