#!/usr/bin/env python3
"""Offline design of the LTI controller of scenarios/acoustic-rig.toml: a phase-compensated
resonant (internal-model) controller from the error microphone y to loudspeaker u1.

For each tone theta_i = 2 pi f_i T the controller has a resonator
    C_i(z) = g (a_i z + b_i) / (z^2 - 2 cos(theta_i) z + 1),
so the closed loop has zeros of the sensitivity at the tones (perfect steady-state
rejection). a_i, b_i put the numerator's phase at theta_i so that, for a small gain g, the
closed-loop poles that start on the unit circle at e^{±j theta_i} move radially inward:
    N_i(e^{j theta}) = -2 j sin(theta) e^{j theta} / G(e^{j theta})
(the service applies u = C y, so the loop closes through 1 - G C),
where G is the plant channel y <- u1 including its 9-sample delay. The script then builds
the exact closed loop (the discretized plant of `plant-proxy describe`, the delay line, the
controller) and checks that its spectral radius is below 1, and prints |S| at and between
the tones. Usage:
    target/release/plant-proxy describe scenarios/acoustic-rig.toml > /tmp/a.json
    python3 scenarios/design/resonant.py /tmp/a.json [gain] [tone,tone,...]
"""
import json, sys
import numpy as np

d = json.load(open(sys.argv[1]))
T = d["sample-period"]
ch = [c for c in d["channels"] if str(c["output"]).lower() == "y0" and str(c["input"]).lower() == "u0"][0]
num, den, delay = np.array(ch["num"]), np.array(ch["den"]), ch["delay-samples"]

def G(z):
    return np.polyval(num, z) / np.polyval(den, z) * z ** (-delay)

tones = [float(f) for f in sys.argv[3].split(",")] if len(sys.argv) > 3 else [800.0, 900.0, 1060.0, 1300.0]
g = float(sys.argv[2]) if len(sys.argv) > 2 else 0.004
# Controller: parallel resonators, realized as a block-diagonal state space.
blocks = []
for f in tones:
    th = 2 * np.pi * f * T
    # The service applies u = C y and the plant gives y = G u + d, so the characteristic
    # equation is 1 - G C = 0: hence the minus sign.
    target = -2j * np.sin(th) * np.exp(1j * th) / G(np.exp(1j * th))
    a = target.imag / np.sin(th)
    b = target.real - a * np.cos(th)
    blocks.append((th, g * a, g * b))

nc = 2 * len(blocks)
Ac = np.zeros((nc, nc)); Bc = np.zeros((nc, 1)); Cc = np.zeros((1, nc)); Dc = np.zeros((1, 1))
for i, (th, a, b) in enumerate(blocks):
    # controllable canonical form of (a z + b)/(z^2 - 2cos z + 1)
    Ac[2*i:2*i+2, 2*i:2*i+2] = [[2*np.cos(th), -1.0], [1.0, 0.0]]
    Bc[2*i, 0] = 1.0
    Cc[0, 2*i:2*i+2] = [a, b]

def C(z):
    return sum((a*z + b) / (z*z - 2*np.cos(th)*z + 1) for th, a, b in blocks)

# Exact closed loop: plant channel realized from num/den (observable form), delay line.
n = len(den) - 1
numf = np.concatenate([np.zeros(len(den) - len(num)), num])
Ap = np.zeros((n, n)); Ap[:, 0] = -den[1:] / den[0]; Ap[:-1, 1:] = np.eye(n - 1)
Bp = (numf[1:] - numf[0] * den[1:] / den[0]).reshape(n, 1) / den[0]
Cp = np.zeros((1, n)); Cp[0, 0] = 1.0
Dp = numf[0] / den[0]
assert abs(Dp) < 1e-12, "plant must be strictly proper with the delay"
# delay line of length `delay`: v_{k+1} = shift, plant input = v_delay
Ad = np.zeros((delay, delay)); Ad[1:, :-1] = np.eye(delay - 1); Bd = np.zeros((delay, 1)); Bd[0, 0] = 1; Cd = np.zeros((1, delay)); Cd[0, -1] = 1
# y = Cp xp; u = Cc xc + Dc y; xc+ = Ac xc + Bc y; xd+ = Ad xd + Bd u; xp+ = Ap xp + Bp Cd xd
N = n + delay + nc
A = np.zeros((N, N))
ip, idl, ic = slice(0, n), slice(n, n + delay), slice(n + delay, N)
A[ip, ip] = Ap; A[ip, idl] = Bp @ Cd
A[idl, idl] = Ad; A[idl, ic] = Bd @ Cc; A[idl, ip] = Bd @ Dc @ Cp
A[ic, ic] = Ac; A[ic, ip] = Bc @ Cp
rho = max(abs(np.linalg.eigvals(A)))
print(f"# gain g = {g}, closed-loop spectral radius = {rho:.6f}", file=sys.stderr)
fs = np.array([f for f in np.linspace(50, 3950, 3901) if min(abs(f - t) for t in tones) > 0.5])
S = np.array([abs(1 / (1 - G(np.exp(1j*2*np.pi*f*T)) * C(np.exp(1j*2*np.pi*f*T)))) for f in fs])
# Note the sign: the service applies u = C y and the loop is y = G u + d, so S = 1/(1 - G C).
print(f"# peak |S| = {20*np.log10(S.max()):.1f} dB at {fs[S.argmax()]:.0f} Hz", file=sys.stderr)
for f in [800.0, 900.0, 1060.0, 1300.0, 1600.0, 2200.0, 3000.0]:
    if f in tones:
        print(f"#   |S({f:.0f} Hz)| = 0 (-inf dB): a resonator sits on this tone", file=sys.stderr)
        continue
    z = np.exp(1j*2*np.pi*f*T)
    print(f"#   |S({f:.0f} Hz)| = {20*np.log10(abs(1/(1 - G(z)*C(z)))):.1f} dB", file=sys.stderr)
fmt = lambda M: "[" + ", ".join("[" + ", ".join(f"{v:.17g}" for v in row) + "]" for row in M) + "]"
print("[controller.ss]")
print("a = " + fmt(Ac)); print("b = " + fmt(Bc)); print("c = " + fmt(Cc)); print("d = [[0.0, 0.0]]".replace(", 0.0]]", "]]") if False else "d = " + fmt(Dc))
sys.exit(0 if rho < 1 else 1)
