#!/usr/bin/env python3
"""Independent check of the ingest's cloud structure (docs/ingest.md, "Verification").

Reads, with ecCodes, the raw GFS values at grid points — cloud bottom/top pressure per layer,
convective cloud bottom/top, CAPE, convective precipitation rate, lifted index — turns the
pressures into altitudes with the point's own gh profile (linear in ln p, numpy), and prints
them beside the probe lines the ingest gives (JSON, one per point, from
`cargo run --release -p stratus-ingest --example probe_points -- FILE OUT.png LAT,LON...`).

usage: check_structure.py FILE PROBES.jsonl   (needs `pip install eccodes numpy`)
"""
import json
import sys

import eccodes as ec
import numpy as np


def read(path):
    fields = {}
    ec.codes_grib_multi_support_on()  # v sits beside u in one message
    with open(path, "rb") as f:
        while True:
            g = ec.codes_grib_new_from_file(f)
            if g is None:
                break
            key = (ec.codes_get(g, "shortName"), ec.codes_get(g, "typeOfLevel"), ec.codes_get(g, "level"))
            ni, nj = ec.codes_get(g, "Ni"), ec.codes_get(g, "Nj")
            v = ec.codes_get_values(g).reshape(nj, ni)
            if ec.codes_get(g, "bitmapPresent"):
                v = np.where(v == ec.codes_get(g, "missingValue"), np.nan, v)
            fields.setdefault(key, v)
            lat1, di = ec.codes_get(g, "latitudeOfFirstGridPointInDegrees"), ec.codes_get(g, "iDirectionIncrementInDegrees")
            ec.codes_release(g)
    return fields, lat1, di


def main():
    path, probes = sys.argv[1], sys.argv[2]
    F, lat1, di = read(path)
    gh = sorted(((lv, v) for (s, t, lv), v in F.items() if s == "gh" and t == "isobaricInhPa"), reverse=True)
    get = lambda name, j, i: F[name][j, i] if name in F else np.nan
    print("| point | layer | GFS bottom / top hPa (ecCodes) | → m with gh (numpy) | probe base / top m | probe source, type | conv. bottom / top hPa | CAPE J/kg | conv. rain mm/h | LI K |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for line in open(probes):
        p = json.loads(line)
        j = int(round((lat1 - p["lat"]) / di))
        i = int(round((p["lon"] % 360) / di))
        lnp = np.log([lv for lv, _ in gh])[::-1]
        z = np.array([v[j, i] for _, v in gh])[::-1]
        alt = lambda pa: float(np.interp(np.log(pa / 100), lnp, z)) if np.isfinite(pa) else np.nan
        cb = get(("pres", "convectiveCloudBottom", 0), j, i) / 100
        ct = get(("pres", "convectiveCloudTop", 0), j, i) / 100
        cape = get(("cape", "surface", 0), j, i)
        cpr = get(("cpr", "surface", 0), j, i) * 3600
        li = get(("lftx", "surface", 0), j, i)
        for lay in p["layers"]:
            k = lay["kind"]
            b = get(("avg_pres", f"{k}CloudBottom", 0), j, i)
            t = get(("avg_pres", f"{k}CloudTop", 0), j, i)
            fmt = lambda x, d=0: "–" if x is None or not np.isfinite(x) else f"{x:.{d}f}"
            print(f"| {p['lat']}°, {p['lon']}° | {k} | {fmt(b / 100)} / {fmt(t / 100)} | {fmt(alt(b))} / {fmt(alt(t))} "
                  f"| {fmt(lay['base_m'])} / {fmt(lay['top_m'])} | {lay['source']}, {lay['type']} (cov. {lay['coverage']:.2f}) "
                  f"| {fmt(cb)} / {fmt(ct)} | {fmt(cape)} | {fmt(cpr, 2)} | {fmt(li, 1)} |")


if __name__ == "__main__":
    main()
