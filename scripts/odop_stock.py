#!/usr/bin/env python3
"""Regenerates catalogs/stock/ms24585_ms24586.csv from the ODOP project's copies of the
military-standard stock spring lists MS24585 (helical compression springs) and MS24586
(helical extension springs), steel (music wire) and corrosion-resistant (302 stainless).

    python3 scripts/odop_stock.py PATH_TO_ODOP_CHECKOUT [--commit HASH]

PATH_TO_ODOP_CHECKOUT is a checkout (or export) of https://github.com/thegrumpys/odop (MIT
licence, Copyright (c) 2018 thegrumpys); the four files read are under
client/src/designtypes/Spring/{Compression,Extension}/. Nothing is downloaded: fetch the
repository yourself. The CSV is committed; builds and tests never run this script.

What the source gives per row: the dash number, outside diameter, wire diameter (inches), total
coils, the free length (compression) or initial tension (extension, lbf), the material and the
end type. It gives no rate and no load limit: this script computes them, and every row's
`source` says so:
- rate (EN 13906-1/-2): G d^4 / (8 D^3 n), D = OD - d, n the active coils: total coils less
  ODOP's inactive coils for the end type (closed & ground: 2; full hook: 0); G of the material
  from Budynas & Nisbett, Shigley's Mechanical Engineering Design (9th ed.), Table 10-5 (music
  wire by diameter: 82.7 GPa below 0.81 mm, 81.7 GPa to 1.60 mm, 81.0 GPa to 3.18 mm; 302
  stainless 69.0 GPa);
- the largest load: the load at the shear stress allowed in the body (Shigley Table 10-7:
  0.45 R_m extension, 0.50 R_m compression, with R_m = A/d^m of Table 10-4: music wire A = 2211
  MPa mm^m, m = 0.145; 302 stainless A = 1867, m = 0.146) with the Bergstraesser factor, for a
  compression spring also no further than solid (total coils x d); the largest deflection the
  deflection at that load (an extension spring's beyond its initial tension);
- an extension spring's free length: its body (total coils + 1) d and a full loop at each end
  (each adds the inside diameter), as springfit's own extension springs.
The part number is the standard's designation: MS24585- or MS24586- and the dash number for the
music-wire springs, MS24585C / MS24586C and the number for the stainless ones (the source lists
them as "C1", "C2", ...). A dash number listed twice in the source is kept once (the first row)
and reported.
"""

import argparse
import json
import math
import os
import sys

INCH = 25.4
LBF = 4.4482216152605
BASE = "client/src/designtypes/Spring"
FILES = [
    ("Compression/MS24585_(SAE-AS24585)_c_stl.json", "compression", "MS24585-"),
    ("Compression/MS24585_(SAE-AS24585)_c_ss.json", "compression", "MS24585"),
    ("Extension/MS24586_(SAE-AS24586)_e_stl.json", "extension", "MS24586-"),
    ("Extension/MS24586_(SAE-AS24586)_e_ss.json", "extension", "MS24586"),
]
INACTIVE = {"Closed&Ground": 2.0, "Full_Hook": 0.0}
HEADER = (
    "vendor,part_number,type,material,d_mm,D_mm,n,length_mm,rate,rate_unit,max_deflection,"
    "max_deflection_unit,max_load,max_load_unit,source,initial_tension_N"
)


def shear_modulus(material, d):
    if material == "MUSIC_WIRE":
        return 82_700.0 if d < 0.81 else 81_700.0 if d <= 1.60 else 81_000.0 if d <= 3.18 else 80_000.0
    return 69_000.0


def tensile(material, d):
    return 2211.0 / d**0.145 if material == "MUSIC_WIRE" else 1867.0 / d**0.146


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("odop", help="a checkout of github.com/thegrumpys/odop")
    ap.add_argument("--commit", default="d1cfc85120db84e981f4c46d2b007f28c3324472", help="the checkout's commit, cited")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "..", "catalogs", "stock", "ms24585_ms24586.csv"))
    a = ap.parse_args()
    rows = []
    for rel, kind, prefix in FILES:
        path = os.path.join(a.odop, BASE, rel)
        with open(path) as f:
            table = json.load(f)
        names = table[0]
        seen = set()
        for raw in table[1:]:
            r = dict(zip(names, raw))
            number = str(r["Name"]).strip()
            if number in seen:
                print(f"{rel}: dash number {number} listed twice; the first row is kept", file=sys.stderr)
                continue
            seen.add(number)
            part = prefix + number
            d = r["Wire_Dia"] * INCH
            od = r["OD_Free"] * INCH
            dm = od - d
            total = r["Coils_T"]
            n = total - INACTIVE[r["End_Type"]]
            g = shear_modulus(r["Material_Type"], d)
            rate = g * d**4 / (8.0 * dm**3 * n)
            w = dm / d
            k = (w + 0.5) / (w - 0.75)
            rm = tensile(r["Material_Type"], d)
            material = "music wire ASTM A228" if r["Material_Type"] == "MUSIC_WIRE" else "302 stainless ASTM A313"
            f_tau = lambda frac: frac * rm * math.pi * d**3 / (8.0 * k * dm)
            source = (
                f"{rel.split('/')[1]} in github.com/thegrumpys/odop@{a.commit[:12]} (MIT licence; the military standard "
                f"{prefix.rstrip('-C')} list): OD, d, coils, "
            )
            if kind == "compression":
                l0 = r["L_Free"] * INCH
                solid = total * d
                travel = min(l0 - solid, f_tau(0.50) / rate)
                if travel <= 0.0:
                    print(f"{part}: free length not above solid; left out", file=sys.stderr)
                    continue
                f0 = ""
                load = rate * travel
                source += "free length from the source; rate and limits computed (scripts/odop_stock.py)"
            else:
                l0 = (total + 1.0) * d + 2.0 * (dm - d)
                f_i = r["Initial_Tension"] * LBF
                fmax = f_tau(0.45)
                if fmax <= f_i:
                    print(f"{part}: initial tension at the stress limit; left out", file=sys.stderr)
                    continue
                travel = (fmax - f_i) / rate
                load = fmax
                f0 = f"{f_i:.4g}"
                source += "initial tension from the source; rate, free length and limits computed (scripts/odop_stock.py)"
            rows.append(
                [
                    "MS24585 (SAE-AS24585)" if kind == "compression" else "MS24586 (SAE-AS24586)",
                    part,
                    kind,
                    material,
                    f"{d:.6g}",
                    f"{dm:.6g}",
                    f"{n:.4g}",
                    f"{l0:.4g}",
                    f"{rate:.5g}",
                    "N/mm",
                    f"{travel:.4g}",
                    "mm",
                    f"{load:.4g}",
                    "N",
                    '"' + source + '"',
                    f0,
                ]
            )
    with open(a.out, "w") as out:
        out.write(
            "# Stock springs of the US military standards MS24585 (SAE-AS24585, helical compression springs) and\n"
            "# MS24586 (SAE-AS24586, helical extension springs), music wire and 302 stainless, as the ODOP project\n"
            f"# lists them (https://github.com/thegrumpys/odop, commit {a.commit}; MIT licence, Copyright (c) 2018\n"
            "# thegrumpys: permission to use, copy, modify and distribute with this notice). Converted from inches\n"
            "# by scripts/odop_stock.py, which says what is the source's and what is computed (the rate, the\n"
            "# largest load and deflection, an extension spring's free length). Part numbers are the standard's\n"
            "# designations (MS24586-12, MS24586C12 for stainless); initial_tension_N is an extension spring's F0.\n"
        )
        out.write(HEADER + "\n")
        for r in rows:
            out.write(",".join(r) + "\n")
    print(f"{len(rows)} rows written to {a.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
