"""Writes the synthetic office luminaire (IES LM-63-2002 and EULUMDAT) for the radiosity
project: a 600 x 600 mm recessed LED luminaire with a square-cell louvre.

Shape (invented, typical of such products): a broad peak slightly off nadir (a mild
batwing, max 1.04 x nadir at gamma = 30 deg), luminance cut-off by the louvre blades: full output
up to gamma_end - 25 deg, a smooth fall to a small stray-light level at gamma_end, where
gamma_end = 68 deg across the blades (C0, C90) and 76 deg along the cell diagonal (C45);
stray light fades to 0 at 90 deg. Nothing upwards. Quadrant symmetric.

Scaled so that the bilinear table's flux is 3400 lm = 0.85 x 4000 lm (lamp flux).
"""
import numpy as np

LAMP_LM = 4000.0
LOR = 0.85
TARGET = LAMP_LM * LOR
C = np.arange(0.0, 90.01, 15.0)          # stored planes, quadrant
G = np.arange(0.0, 90.01, 5.0)           # gamma, downward hemisphere


def smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def shape(c, g):
    gr = np.radians(g)
    end = 68.0 + 8.0 * np.sin(np.radians(2 * c)) ** 2
    body = np.cos(gr) ** 0.55 * (1.0 + 0.22 * np.sin(1.6 * gr) ** 2)
    cut = 1.0 - smoothstep(end - 25.0, end, g)
    stray = 0.012 * (1.0 - smoothstep(end, 90.0, g)) * np.cos(gr) ** 0.5
    v = body * cut + stray * (1 - cut)
    return np.where(g >= 90.0, 0.0, v)


def weights(a, b):
    h = b - a
    w0 = np.cos(a) - (np.sin(b) - np.sin(a)) / h
    w1 = (np.sin(b) - np.sin(a)) / h - np.cos(b)
    return w0, w1


def table_flux(c_full, g, I):
    """Exact flux of the bilinear interpolant, C periodic (I[c, g], c_full ends at 360)."""
    gr = np.radians(g)
    P = np.zeros(len(c_full))
    for j in range(len(g) - 1):
        w0, w1 = weights(gr[j], gr[j + 1])
        P += I[:, j] * w0 + I[:, j + 1] * w1
    dc = np.radians(np.diff(c_full))
    return float(np.sum(dc * 0.5 * (P[:-1] + P[1:])))


def expand_quadrant(I):
    # planes 0..90 -> 0..360: 180-c, 180+c, 360-c
    rows = list(I) + list(I[-2::-1]) + list(I[1:]) + list(I[-2::-1])
    return np.arange(0.0, 360.01, 15.0), np.array(rows)


def brute_flux(c_full, g, I, n=400):
    """Midpoint quadrature of the bilinear interpolant (cross-check of table_flux)."""
    cs = (np.arange(n * 4) + 0.5) * 360.0 / (n * 4)
    gs = (np.arange(n) + 0.5) * 90.0 / n
    # interpolate along g then c
    Ig = np.array([np.interp(gs, g, row) for row in I])        # planes x gs
    Icg = np.array([np.interp(cs, c_full, Ig[:, k]) for k in range(len(gs))])  # gs x cs
    dA = np.radians(360.0 / (n * 4)) * np.radians(90.0 / n)
    return float(np.sum(Icg * np.sin(np.radians(gs))[:, None]) * dA)


raw = np.array([[shape(c, g) for g in G] for c in C])
cf, full = expand_quadrant(raw)
scale = TARGET / table_flux(cf, G, full)
cd = raw * scale
_, full_cd = expand_quadrant(cd)
print("I0 =", cd[0, 0], "max =", cd.max(), "at", np.unravel_index(cd.argmax(), cd.shape))
print("flux unrounded", table_flux(cf, G, full_cd), "brute", brute_flux(cf, G, full_cd))

ies_vals = np.round(cd, 1)
_, full_ies = expand_quadrant(ies_vals)
print("flux IES-rounded", table_flux(cf, G, full_ies))
ldt_vals = np.round(cd / (LAMP_LM / 1000.0), 1)           # cd/klm
_, full_ldt = expand_quadrant(ldt_vals * LAMP_LM / 1000.0)
print("flux LDT-rounded", table_flux(cf, G, full_ldt))
print("max |IES - LDT| cd", np.abs(ies_vals - ldt_vals * 4).max())
for k, c in enumerate(C):
    print(f"C{c:4.0f}", " ".join(f"{v:7.1f}" for v in ies_vals[k]))


def fmt(v):
    return f"{v:.1f}"


def wrap(values, per_line=10):
    vals = [fmt(v) for v in values]
    return "\n".join(" ".join(vals[i:i + per_line]) for i in range(0, len(vals), per_line))


ies = [
    "IESNA:LM-63-2002",
    "[TEST] SYNTHETIC-RL600-01: synthetic data written for the radiosity project, not a measurement",
    "[TESTLAB] none (synthetic)",
    "[ISSUEDATE] 2025-01-01",
    "[MANUFAC] radiosity project example (not a real product)",
    "[LUMCAT] RL600-3400-840",
    "[LUMINAIRE] Recessed LED luminaire 600 x 600 mm, square-cell low-glare louvre",
    "[LAMP] LED module, 4000 lm, 4000 K, CRI 80",
    "[BALLAST] integral LED driver",
    "[OTHER] Synthetic distribution: quadrant symmetric, mild batwing (max near 30 deg),",
    "[MORE] louvre cut-off at 68 deg (C0/C90) to 76 deg (C45), nothing upwards.",
    "[MORE] Table flux 3400 lm = 0.85 x 4000 lm lamp flux; input 28 W.",
    "TILT=NONE",
    f"1 {LAMP_LM:.0f} 1 {len(G)} {len(C)} 1 2 0.56 0.56 0",
    "1 1 28",
    " ".join(f"{g:.0f}" for g in G),
    " ".join(f"{c:.0f}" for c in C),
]
for row in ies_vals:
    ies.append(wrap(row))
open("recessed_louvre.ies", "w", newline="\r\n").write("\n".join(ies) + "\n")

# EULUMDAT: Isym 4, Mc 24 (Dc 15), Ng 37 (Dg 5, 0..180, zeros above 90).
G37 = np.arange(0.0, 180.01, 5.0)
ldt = [
    "radiosity project example - SYNTHETIC photometry, not a real product",
    "3",                      # Ityp: point source, other symmetry
    "4",                      # Isym: C0-C180 and C90-C270
    "24", "15", "37", "5",
    "SYNTHETIC-RL600-01: written for the radiosity project, not measured",
    "Recessed LED luminaire 600 x 600 mm, square-cell low-glare louvre",
    "RL600-3400-840",
    "rl600.ldt",
    "2025-01-01 / radiosity project",
    "597", "597", "45",       # luminaire L, W, H (mm)
    "560", "560",             # luminous area L, W (mm)
    "0", "0", "0", "0",       # luminous area heights C0, C90, C180, C270
    "100",                    # DFF %
    "85",                     # LORL %
    "1",                      # conversion factor
    "0",                      # tilt
    "1",                      # lamp sets
    "1", "LED module 840", f"{LAMP_LM:.0f}", "4000", "80", "28",
]
# Direct ratios k = 0.6..5: illustrative values for a medium-wide downlight, not computed.
ldt += ["0.47", "0.56", "0.63", "0.69", "0.74", "0.80", "0.84", "0.87", "0.91", "0.94"]
ldt += [f"{c:.0f}" for c in np.arange(0.0, 345.01, 15.0)]
ldt += [f"{g:.0f}" for g in G37]
for row in ldt_vals:
    full_row = list(row) + [0.0] * (len(G37) - len(G))
    ldt += [fmt(v) for v in full_row]
open("recessed_louvre.ldt", "w", newline="\r\n").write("\n".join(ldt) + "\n")
