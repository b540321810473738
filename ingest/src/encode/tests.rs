//! The writer against the WMO octet layout, two independent decoders and the reader.

use super::bits::{micro_deg, scaled_level, sm16, sm32, sm8};
use super::fixtures::*;
use super::*;
use gribberish::message::{Message, MessageIterator};

/// Half a packing step: the worst rounding error of simple packing.
fn tolerance(m: &[u8]) -> f64 {
    let (p, _) = find_section(m, 5).unwrap();
    let e = m[p + 15..p + 17]
        .try_into()
        .map(u16::from_be_bytes)
        .unwrap();
    let d = m[p + 17..p + 19]
        .try_into()
        .map(u16::from_be_bytes)
        .unwrap();
    let sm = |x: u16| {
        if x & 0x8000 != 0 {
            -((x & 0x7fff) as i32)
        } else {
            x as i32
        }
    };
    0.5 * 2f64.powi(sm(e)) / 10f64.powi(sm(d)) + 1e-9
}

#[test]
fn sign_magnitude() {
    assert_eq!(sm32(-40_000_000), 0x8000_0000 | 40_000_000);
    assert_eq!(sm16(-3), 0x8003);
    assert_eq!(sm8(-1), 0x81);
    assert_eq!(micro_deg(-0.5), 0x8000_0000 | 500_000);
    assert_eq!(scaled_level(50000.0), (0, 50000));
    assert_eq!(scaled_level(0.5), (1, 5));
    assert_eq!(scaled_level(-2.25), (2, 0x8000_0000 | 225));
}

#[test]
fn octets_are_where_the_spec_puts_them() {
    let f = small_field(param::RH, 500.0, rh_values(500.0));
    let m = encode_message(&f);
    assert_eq!(&m[..4], b"GRIB");
    assert_eq!(m[7], 2);
    assert_eq!(
        u64::from_be_bytes(m[8..16].try_into().unwrap()),
        m.len() as u64
    );
    assert_eq!(&m[m.len() - 4..], b"7777");
    let o = |sec: u8, octet: usize| find_section(&m, sec).unwrap().0 + octet - 1;
    let u32at = |at: usize| u32::from_be_bytes(m[at..at + 4].try_into().unwrap());
    assert_eq!(u16::from_be_bytes([m[o(1, 6)], m[o(1, 7)]]), 7);
    assert_eq!(u16::from_be_bytes([m[o(1, 13)], m[o(1, 14)]]), 2024);
    assert_eq!(m[o(3, 15)], 6);
    assert_eq!(u32at(o(3, 31)), NI);
    assert_eq!(u32at(o(3, 35)), NJ);
    assert_eq!(u32at(o(3, 47)), 50_000_000);
    assert_eq!(m[o(3, 55)], 0x30);
    assert_eq!(u32at(o(3, 64)), 1_000_000);
    assert_eq!(m[o(3, 72)], 0);
    assert_eq!((m[o(4, 10)], m[o(4, 11)], m[o(4, 18)]), (1, 1, 1));
    assert_eq!(u32at(o(4, 19)), 12);
    assert_eq!((m[o(4, 23)], m[o(4, 24)]), (100, 0));
    assert_eq!(u32at(o(4, 25)), 50_000);
    assert_eq!(m[o(4, 29)], 255);
    assert_eq!(u32at(o(5, 6)), NI * NJ);
    assert_eq!(m[o(5, 20)], 10);
    assert_eq!(m[o(6, 6)], 255);
}

#[test]
fn negative_longitudes_use_sign_magnitude() {
    let mut f = small_field(param::RH, 500.0, rh_values(500.0));
    (f.lon1, f.lon2) = (-40.0, -35.0);
    let m = encode_message(&f);
    let (p, _) = find_section(&m, 3).unwrap();
    assert_eq!(
        &m[p + 50..p + 54],
        &(0x8000_0000u32 | 40_000_000).to_be_bytes()
    );
}

#[test]
fn packing_round_trips_within_half_a_step() {
    let v: Vec<f64> = (0..1000)
        .map(|k| -40.0 + (k as f64 * 0.37).sin() * 300.0)
        .collect();
    for (d, bits) in [(0, 8), (1, 12), (2, 16), (-1, 6), (0, 24)] {
        let p = pack_simple(&v, d, bits);
        let step = 2f64.powi(p.binary_scale as i32) / 10f64.powi(d as i32);
        let mut pos = 0usize;
        for &y in &v {
            let mut x = 0u64;
            for _ in 0..bits {
                let bit = (p.data[pos / 8] >> (7 - pos % 8)) & 1;
                x = (x << 1) | bit as u64;
                pos += 1;
            }
            let back = (p.reference as f64 + x as f64 * 2f64.powi(p.binary_scale as i32))
                / 10f64.powi(d as i32);
            assert!(
                (back - y).abs() <= 0.5 * step + 1e-6,
                "{d} {bits}: {y} -> {back}"
            );
        }
    }
}

#[test]
fn gribberish_decodes_what_we_encode() {
    let fields = valid_rh_fields();
    let bytes = encode_file(&fields);
    let msgs: Vec<Message> = MessageIterator::from_data(&bytes, 0).collect();
    assert_eq!(msgs.len(), fields.len());
    for (m, f) in msgs.iter().zip(&fields) {
        let abbrev = m.variable_abbrev().unwrap();
        let want = if f.category == 1 { "RH" } else { "HGT" };
        assert_eq!(abbrev.to_uppercase(), want);
        let (_, level) = m.first_fixed_surface().unwrap();
        assert_eq!(level, Some(f.level_value));
        assert_eq!(m.grid_dimensions().unwrap(), (NJ as usize, NI as usize));
        let data = m.data().unwrap();
        let tol = tolerance(&bytes[m.byte_offset()..]);
        assert_eq!(data.len(), f.values.len());
        for (a, b) in data.iter().zip(&f.values) {
            assert!((a - b).abs() <= tol, "{a} vs {b} (tolerance {tol})");
        }
        assert_eq!(
            m.forecast_date().unwrap().to_rfc3339(),
            "2024-06-01T12:00:00+00:00"
        );
    }
}

#[test]
fn gribberish_maps_the_bitmap_to_nan() {
    let bytes = valid_rh_with_bitmap();
    let m = MessageIterator::from_data(&bytes, 0).next().unwrap();
    let data = m.data().unwrap();
    let want = rh_values(700.0);
    assert_eq!(data.len(), want.len());
    for (k, (a, b)) in data.iter().zip(&want).enumerate() {
        if [0, NI as usize - 1, (NI * NJ) as usize - 1].contains(&k) {
            assert!(a.is_nan(), "point {k} should be missing");
        } else {
            assert!((a - b).abs() <= 0.051, "{a} vs {b}");
        }
    }
}

#[test]
fn grib1_fixture_is_well_formed() {
    let bytes = grib1_rh();
    assert_eq!(&bytes[..4], b"GRIB");
    assert_eq!(bytes[7], 1);
    let total = u32::from_be_bytes([0, bytes[4], bytes[5], bytes[6]]) as usize;
    assert_eq!(total, bytes.len());
    let m = MessageIterator::from_data(&bytes, 0).next().unwrap();
    let data = m.data().unwrap();
    assert_eq!(data.len(), GRIB1_VALUES.len());
    for (a, b) in data.iter().zip(GRIB1_VALUES) {
        assert!((a - b).abs() < 1e-3, "{a} vs {b}");
    }
    assert_eq!(m.first_fixed_surface().unwrap().1, Some(500.0));
}

#[test]
fn fixtures_are_small_and_the_reader_refuses_the_bad_ones() {
    for (name, valid, bytes) in all() {
        assert!(bytes.len() < 2048, "{name} is {} bytes", bytes.len());
        let verdict = crate::grib::scan(&bytes).and_then(|infos| {
            infos
                .iter()
                .map(|i| crate::grib::decode_values(&bytes, i).map(|_| ()))
                .collect::<Result<Vec<()>, _>>()
        });
        // The reader keeps a message whose date is impossible (reference time None);
        // whether to refuse it is the reader's policy, so only "no panic" is checked.
        if name != "bad_reference_date" {
            assert_eq!(verdict.is_ok(), valid, "{name}: {verdict:?}");
        }
    }
    for seed in 1..50 {
        let bytes = flipped_data_bits(seed);
        if let Ok(infos) = crate::grib::scan(&bytes) {
            for i in &infos {
                let _ = crate::grib::decode_values(&bytes, i);
            }
        }
    }
}

/// Cross-check against ecCodes, an independent decoder:
/// `pip install eccodes && cargo test -p stratus-ingest eccodes -- --ignored`.
#[test]
#[ignore = "needs python3 with the eccodes package"]
fn eccodes_decodes_what_we_encode() {
    let ok = std::process::Command::new("python3")
        .args(["-c", "import eccodes"])
        .status()
        .is_ok_and(|s| s.success());
    assert!(ok, "python3 -c 'import eccodes' fails: pip install eccodes");
    let mut fields = valid_rh_fields();
    // Negative longitudes, negative values, a bit-map, fine and coarse packing.
    let mut t = small_field(param::T, 925.0, vec![0.0; (NI * NJ) as usize]);
    (t.lon1, t.lon2) = (-40.0, -35.0);
    t.values = (0..NI * NJ).map(|k| -12.5 + 0.731 * k as f64).collect();
    (t.decimal_scale, t.bits) = (2, 16);
    fields.push(t);
    let mut rh = small_field(param::RH, 250.0, rh_values(250.0));
    rh.values[7] = f64::NAN;
    rh.values[8] = f64::NAN;
    (rh.decimal_scale, rh.bits) = (0, 5);
    rh.forecast_hours = 384;
    fields.push(rh);
    let dir = tempfile::tempdir().unwrap();
    let grib = dir.path().join("f.grib2");
    std::fs::write(&grib, encode_file(&fields)).unwrap();
    let mut expect = String::new();
    for f in &fields {
        let short = match (f.category, f.number) {
            (1, 1) => "r",
            (3, 5) => "gh",
            _ => "t",
        };
        let vals: Vec<String> = f.values.iter().map(|v| format!("{v}")).collect();
        expect += &format!(
            "{short} {} {} {} {} {} {} {} {} {}\n",
            f.level_value / 100.0,
            f.ni,
            f.nj,
            f.lat1,
            f.lon1.rem_euclid(360.0),
            f.lat2,
            f.lon2.rem_euclid(360.0),
            f.forecast_hours,
            vals.join(",")
        );
    }
    let exp = dir.path().join("expect.txt");
    std::fs::write(&exp, expect).unwrap();
    let g1 = dir.path().join("g1.grib");
    std::fs::write(&g1, grib1_rh()).unwrap();
    let g1_vals: Vec<String> = GRIB1_VALUES.iter().map(|v| v.to_string()).collect();
    let out = std::process::Command::new("python3")
        .args(["-c", ECCODES_CHECK])
        .arg(&grib)
        .arg(&exp)
        .arg(&g1)
        .arg(g1_vals.join(","))
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    println!("{text}");
    assert!(out.status.success(), "ecCodes check failed:\n{text}");
}

const ECCODES_CHECK: &str = r#"
import sys, math, eccodes
grib, exp, g1, g1vals = sys.argv[1:5]
lines = [l.split() for l in open(exp).read().splitlines()]
worst = 0.0
with open(grib, 'rb') as f:
    for k, want in enumerate(lines):
        h = eccodes.codes_grib_new_from_file(f)
        assert h is not None, f'message {k} missing'
        g = lambda key: eccodes.codes_get(h, key)
        short, lev, ni, nj, la1, lo1, la2, lo2, step, vals = want
        got = (g('shortName'), g('typeOfLevel'), g('level'), g('Ni'), g('Nj'), g('step'), g('edition'))
        assert got == (short, 'isobaricInhPa', int(float(lev)), int(ni), int(nj), int(step), 2), (k, got)
        for key, v in [('latitudeOfFirstGridPointInDegrees', la1), ('longitudeOfFirstGridPointInDegrees', lo1),
                       ('latitudeOfLastGridPointInDegrees', la2), ('longitudeOfLastGridPointInDegrees', lo2)]:
            d = g(key) - float(v)
            if key.startswith('lon'):
                d = (d + 180.0) % 360.0 - 180.0
            assert abs(d) < 1e-6, (k, key, g(key), v)
        assert g('dataDate') == 20240601 and g('dataTime') == 0, k
        assert g('centre') == 'kwbc' and g('shapeOfTheEarth') == 6, k
        tol = 0.5 * 2.0 ** g('binaryScaleFactor') / 10.0 ** g('decimalScaleFactor') + 1e-9
        miss = g('missingValue')
        out = eccodes.codes_get_values(h)
        exp_vals = [float(x) for x in vals.split(',')]
        assert len(out) == len(exp_vals), k
        for a, b in zip(out, exp_vals):
            if math.isnan(b):
                assert a == miss, (k, a)
            else:
                assert abs(a - b) <= tol, (k, a, b, tol)
                worst = max(worst, abs(a - b) / tol)
        print(f'{short:>2} {lev:>6} hPa {ni}x{nj} ok (E={g("binaryScaleFactor")} D={g("decimalScaleFactor")} '
              f'bits={g("bitsPerValue")} missing={g("numberOfMissing")})')
        eccodes.codes_release(h)
    assert eccodes.codes_grib_new_from_file(f) is None, 'extra message'
print(f'worst error {worst:.3f} of the half-step tolerance')
with open(g1, 'rb') as f:
    h = eccodes.codes_grib_new_from_file(f)
    g = lambda key: eccodes.codes_get(h, key)
    assert (g('edition'), g('indicatorOfParameter'), g('shortName'), g('level'), g('Ni'), g('Nj')) == (1, 52, 'r', 500, 4, 3)
    out = eccodes.codes_get_values(h)
    assert all(abs(a - float(b)) < 1e-4 for a, b in zip(out, g1vals.split(','))), list(out)
    print('GRIB1 fixture ok', g('dataDate'), g('step'), g('latitudeOfFirstGridPointInDegrees'), g('longitudeOfLastGridPointInDegrees'))
"#;
