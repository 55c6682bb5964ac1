"""Run Siconos on a friction chain or the bouncing ball: a script for the *system* Python, not for nsbench's.

Debian's ``python3-siconos`` is built for the system interpreter and numpy 1.x, so it
cannot be imported into nsbench's environment. ``siconos-moreau-jean`` runs this file
with that interpreter; it imports numpy and Siconos only (never nsbench), reads one JSON
request on stdin, writes the trajectory and the friction forces as ``.npy`` files
(plain float64 arrays, readable by any numpy) and prints one JSON line on stdout.

The chain is Siconos's first-order linear system ``z' = A z + B lambda`` in nsbench's
state layout ``z = [x1, v1, ..., xn, vn]`` (``FirstOrderLinearTIDS``), with one relay per
block on its velocity relative to the belt, ``y_i = v_i - v0`` (``FirstOrderLinearTIR``
with ``e = -v0``), ``lambda_i`` its friction force in ``[-fr_i, fr_i]`` (``RelayNSL``), and
the ``EulerMoreauOSI`` theta-scheme with the friction force taken implicitly: on this
linear system the same discrete equations as Moreau-Jean's. A request ``{"probe": true}``
only imports Siconos and prints its version; a request with ``"model": "ball"`` runs the
bouncing ball (:func:`ball_moreau_jean`), its ``.npy`` files holding the states and the
impulse of each step; ``"model": "ball-event-driven"`` runs Siconos's event-driven scheme
on it (:func:`ball_event_driven`).
"""

import json
import sys

import numpy as np


def main() -> int:
    req = json.loads(sys.stdin.read())
    import siconos
    import siconos.kernel as sk
    import siconos.numerics as sn

    if req.get("probe"):
        print(json.dumps({"ok": True, "version": getattr(siconos, "__version__", "?")}))
        return 0
    if req.get("model") == "ball":
        return ball_moreau_jean(req, sk)
    if req.get("model") == "ball-event-driven":
        return ball_event_driven(req, sk)
    m = np.array(req["m"], dtype=float)
    n = m.size
    C, K = np.array(req["C"], dtype=float), np.array(req["K"], dtype=float)
    fr, v0 = np.array(req["fr"], dtype=float), float(req["v0"])
    theta, h, steps, t0 = float(req["theta"]), float(req["h"]), int(req["n_steps"]), float(req["t0"])
    A = np.zeros((2 * n, 2 * n))
    B = np.zeros((2 * n, n))
    Cy = np.zeros((n, 2 * n))
    for i in range(n):
        A[2 * i, 2 * i + 1] = 1.0
        for j in range(n):
            A[2 * i + 1, 2 * j] = -K[i, j] / m[i]
            A[2 * i + 1, 2 * j + 1] = -C[i, j] / m[i]
        B[2 * i + 1, i] = 1.0 / m[i]
        Cy[i, 2 * i + 1] = 1.0
    z0 = np.array(req["y0"], dtype=float)
    ds = sk.FirstOrderLinearTIDS(z0, A)
    nsds = sk.NonSmoothDynamicalSystem(t0, t0 + steps * h)
    nsds.insertDynamicalSystem(ds)
    inters = []
    for i in range(n):  # one relay per block (RelayNSL takes scalar bounds)
        rel = sk.FirstOrderLinearTIR(Cy[i : i + 1].copy(), B[:, i : i + 1].copy())
        rel.setePtr(np.array([-v0]))
        inter = sk.Interaction(sk.RelayNSL(1, -float(fr[i]), float(fr[i])), rel)
        nsds.link(inter, ds)
        inters.append(inter)
    osi = sk.EulerMoreauOSI(theta)
    td = sk.TimeDiscretisation(t0, h)
    osnspb = sk.Relay(getattr(sn, req.get("solver", "SICONOS_RELAY_LEMKE")))
    sim = sk.TimeStepping(nsds, td, osi, osnspb)
    z = np.empty((steps + 1, 2 * n))
    lam = np.zeros((steps + 1, n))
    z[0] = z0
    k = 0
    while sim.hasNextEvent() and k < steps:
        sim.computeOneStep()
        k += 1
        z[k] = np.array(ds.x())
        lam[k] = [float(np.array(inter.lambda_(0)).reshape(-1)[0]) for inter in inters]
        sim.nextStep()
    np.save(req["out"] + ".z.npy", z[: k + 1])
    np.save(req["out"] + ".lambda.npy", lam[: k + 1])
    print(json.dumps({"ok": True, "steps": k, "version": getattr(siconos, "__version__", "?")}))
    return 0


def ball_model(req, sk, t_end):
    """The bouncing ball as Siconos's classic: a unit mass under gravity, one contact with the ground.

    ``LagrangianLinearTIDS`` (mass 1, no stiffness) with the weight as a constant external
    force, ``LagrangianLinearTIR`` ``y = x`` (the height), ``NewtonImpactNSL(e)``.
    """
    ds = sk.LagrangianLinearTIDS([float(req["y0"][0])], [float(req["y0"][1])], np.eye(1))
    ds.setFExtPtr(np.array([-float(req["g"])]))
    inter = sk.Interaction(sk.NewtonImpactNSL(float(req["e"])), sk.LagrangianLinearTIR(np.eye(1)))
    nsds = sk.NonSmoothDynamicalSystem(float(req["t0"]), t_end)
    nsds.insertDynamicalSystem(ds)
    nsds.link(inter, ds)
    return ds, inter, nsds


def ball_moreau_jean(req, sk):
    """``MoreauJeanOSI(theta)`` with an LCP per step; saves the states and the impulse of each step.

    Siconos activates the contact in a step when the height predicted half a step ahead,
    ``x_k + h v_k / 2``, is not above the ground, and its LCP is Newton's law at the
    velocity level, ``0 <= v_{k+1} + e v_k  _|_  P >= 0``; ``lambda(1)`` is that impulse.
    """
    theta, h, steps, t0 = float(req["theta"]), float(req["h"]), int(req["n_steps"]), float(req["t0"])
    ds, inter, nsds = ball_model(req, sk, t0 + steps * h)
    sim = sk.TimeStepping(nsds, sk.TimeDiscretisation(t0, h), sk.MoreauJeanOSI(theta), sk.LCP())
    z = np.empty((steps + 1, 2))
    imp = np.zeros((steps + 1, 1))
    z[0] = req["y0"]
    k = 0
    while sim.hasNextEvent() and k < steps:
        sim.computeOneStep()
        k += 1
        z[k] = (ds.q()[0], ds.velocity()[0])
        imp[k, 0] = float(np.array(inter.lambda_(1)).reshape(-1)[0])
        sim.nextStep()
    np.save(req["out"] + ".z.npy", z[: k + 1])
    np.save(req["out"] + ".lambda.npy", imp[: k + 1])
    print(json.dumps({"ok": True, "steps": k}))
    return 0


def ball_event_driven(req, sk):
    """``EventDriven`` with ``LsodarOSI``: LSODAR between events, an impact LCP at each, an acceleration LCP.

    A sample is saved after every processed event (the output grid of step ``h`` and each
    impact, which LSODAR's root finder places on the height); its impulse is Siconos's
    ``p(1)`` at an impact (0 otherwise) and its mode 1 once the contact is in index set 2
    (resting contact: Siconos has stopped the impacts). A sample at the time of the one
    before replaces it. Stops after ``max_events`` events.
    """
    t0, t_end, h, cap = float(req["t0"]), float(req["t_end"]), float(req["h"]), int(req["max_events"])
    ds, inter, nsds = ball_model(req, sk, t_end)
    sim = sk.EventDriven(nsds, sk.TimeDiscretisation(t0, h))
    sim.insertIntegrator(sk.LsodarOSI())
    sim.insertNonSmoothProblem(sk.LCP(), sk.SICONOS_OSNSP_ED_IMPACT)
    sim.insertNonSmoothProblem(sk.LCP(), sk.SICONOS_OSNSP_ED_SMOOTH_ACC)
    rows = [(t0, float(req["y0"][0]), float(req["y0"][1]), 0.0, 0.0)]
    k = 0
    while sim.hasNextEvent() and k < cap:
        sim.advanceToEvent()
        impact = sim.eventsManager().nextEvent().getType() == 2  # a non-smooth event
        sim.processEvents()
        k += 1
        row = (
            sim.startingTime(),
            ds.q()[0],
            ds.velocity()[0],
            float(ds.p(1)[0]) if impact else 0.0,
            1.0 if len(sim.indexSet(2).interactions()) else 0.0,
        )
        if row[0] == rows[-1][0]:
            row = row[:3] + (max(row[3], rows[-1][3]),) + row[4:]
            rows[-1] = row
        else:
            rows.append(row)
    out = np.array(rows, dtype=float)
    np.save(req["out"] + ".z.npy", out[:, :3])  # t, x, v
    np.save(req["out"] + ".lambda.npy", out[:, 3:])  # impulse, resting
    print(json.dumps({"ok": True, "events": k, "done": bool(not sim.hasNextEvent())}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
