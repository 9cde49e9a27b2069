"""Collision detection on the real UR10e's logs (../shared/data/real; test data, never copied into
the repository): the model identified on a Fourier excitation, thresholds set on the first half
of a collision-free log. Skipped when the folder is absent (a clone has none)."""
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest

from codegen.evaluate.detect import detect
from codegen.logs.identify import identify
from codegen.logs.recording import Recording
from models import load_robot

ROOT = Path(__file__).resolve().parents[2]
FOLDER = Path(os.environ.get("CODEGEN_REAL_LOGS") or ROOT.parent / "shared" / "data" / "real")
pytestmark = [pytest.mark.real, pytest.mark.long,
              pytest.mark.skipif(not (FOLDER / "ur10e_push.npz").is_file(),
                                 reason=f"no real logs in {FOLDER} (set CODEGEN_REAL_LOGS)")]


def _segment(npz, k, a=0.0, b=1.0):
    i0, i1 = int(npz["seg_start"][k]), int(npz["seg_start"][k + 1])
    lo, hi = i0 + int(a * (i1 - i0)), i0 + int(b * (i1 - i0))
    return Recording(t=npz["t"][lo:hi], q=npz["q"][lo:hi], tau=npz["tau"][lo:hi], qd=None,
                     joint_names=[str(j) for j in npz["joint_names"]])


def _names(npz):
    return [str(s) for s in npz["seg_names"]]


@pytest.fixture(scope="module")
def ur10e():
    """(identified model, collision-free segments, push logs)."""
    s = np.load(FOLDER / "ur10e_real_segments.npz", allow_pickle=True)
    p = np.load(FOLDER / "ur10e_push.npz", allow_pickle=True)
    tmp = tempfile.mkdtemp()
    (Path(tmp) / "ur10e.urdf").write_text(str(s["urdf"][0]))
    robot = load_robot(urdf=Path(tmp) / "ur10e.urdf")
    excitation = next(k for k, n in enumerate(_names(s)) if "harm" in n and "Load" not in n)
    files = identify(_segment(s, excitation), robot).write(tmp)     # the URDF's prior keeps what the log leaves
    return load_robot(urdf=files["urdf"]), s, p


@pytest.mark.xfail(strict=True, raises=Exception, reason="measured 8 Dec 2026: the model identify now writes for the "
                   "UR10e has a Coulomb width of 0.02 rad/s, stiff on wrist 3's 0.00024 kg m^2 (rate 2.9e5 1/s): "
                   "no stable discretisation of the momentum step at the log's 10 ms within 64 sub-steps")
def test_every_push_log_has_events_and_held_out_motion_fewer(ur10e):
    """Thresholds set on the first half of the point-to-point validation log: each push log (the arm
    held while a person pushes it) has events, more per second than the held-out second half."""
    model, s, p = ur10e
    ptp = next(k for k, n in enumerate(_names(s)) if "ptp" in n)
    clean = _segment(s, ptp, 0.0, 0.5)
    held = detect(model, _segment(s, ptp, 0.5, 1.0), clean=clean)
    rate_held = len(held.events) / (held.t[-1] - held.t[0])
    for k in range(len(_names(p))):
        det = detect(model, _segment(p, k), clean=clean)
        assert det.events, _names(p)[k]
        assert len(det.events) / (det.t[-1] - det.t[0]) > rate_held


@pytest.mark.xfail(strict=True, reason="measured: 5, 1 and 1 events on the held-out halves of the ptp, "
                   "a 40 s excitation and the free log at one false alarm an hour: a 27 s calibration half "
                   "does not hold the model error of the other half's moves (docs/observers/momentum.md)")
def test_no_alarm_on_the_held_out_half_of_collision_free_logs(ur10e):
    model, s, _ = ur10e
    names = _names(s)
    for k in (next(i for i, n in enumerate(names) if "ptp" in n), 1, next(i for i, n in enumerate(names) if "free" in n)):
        det = detect(model, _segment(s, k, 0.5, 1.0), clean=_segment(s, k, 0.0, 0.5))
        assert not det.events, (names[k], [(e["start"], e["end"]) for e in det.events])
