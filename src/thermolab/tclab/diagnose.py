"""``diagnose``: check the way to a rig step by step, as the ``tclab`` package checks a kit."""

from __future__ import annotations

import time

from thermolab.client import Lab
from thermolab.tclab.labtime import labtime
from thermolab.tclab.remote import TCLab

__all__ = ["diagnose"]


def _heading(text: str) -> None:
    print(f"\n{text}\n{'-' * len(text)}")


def diagnose(
    port: str = "",
    *,
    url: str | None = None,
    token: str | None = None,
    rig: str | None = None,
    heat: float = 30.0,
) -> bool:
    """Check the lab, the rig, its sensor, its heater and its speed; print what is found.

    The ``tclab`` package's checks, on a lab rig: the lab is reached and
    speaks this client's API, the rig is a kit (heater in %, sensor in °C),
    ``T1`` reads, ``Q1`` takes a fractional value, the heater at 100 % for
    ``heat`` lab seconds warms the sensor by at least 0.8 °C, and ``T1``
    reads per second over 2 s.

    Parameters
    ----------
    port : str
        Accepted for the ``tclab`` signature; a lab rig has no port (refused if given).
    url, token, rig : str, optional
        As for :class:`~thermolab.tclab.TCLab`.
    heat : float
        Lab seconds of heating (30 s on a kit; a twin at 20x takes 1.5 s).

    Returns
    -------
    bool
        Whether every check passed.
    """
    _heading("Checking the lab")
    with Lab(url, token) as lab:
        print(f"ThermoLab {lab.info.get('version')} (API {lab.info.get('api')}) at {lab.url}")
        for found in lab.rigs():
            inp = found["input"]
            print(
                f"  rig {found['id']!r} ({found['kind']}): input {inp['min']:g}–{inp['max']:g} "
                f"{inp['unit']}, output in {found.get('outputUnit')}, state {found['state']}"
            )
    _heading("Testing TCLab on the rig")
    healthy = True
    with TCLab(port, url=url, token=token, rig=rig) as kit:
        t1 = kit.T1
        print(f"T1 = {t1} °C")
        q1 = kit.Q1(0.5)
        print(f"We wrote Q1 = 0.5 % and read back Q1 = {kit.Q1()} %")
        healthy &= q1 == 0.5
        print(f"Heater 1 at 100 % for {heat:g} lab s (the rig runs at {kit.speedup:g}x)...")
        kit.Q1(100)
        labtime.sleep(heat)
        final = kit.T1
        kit.Q1(0)
        print(f"T1 went from {t1} °C to {final} °C")
        if final - t1 < 0.8:
            healthy = False
            print("The temperature went up less than expected (0.8 °C): check the heater.")
        _heading("Throughput check")
        start, reads = time.monotonic(), 0
        while time.monotonic() - start < 2.0:
            _ = kit.T1
            reads += 1
        print(f"{reads / (time.monotonic() - start):.1f} T1 reads per second")
    print("\nDiagnostics complete" + ("" if healthy else ": see the problems above"))
    return healthy
