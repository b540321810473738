fn main() {
    let bytes = std::fs::read("data-samples/synthetic-gfs-rh.grib2").unwrap();
    let ecc: Vec<f64> = std::fs::read("/tmp/sample_vals.f64").unwrap().chunks(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
    let infos = stratus_ingest::grib::scan(&bytes).unwrap();
    let mut off = 0; let mut worst = 0f64;
    for i in &infos {
        let f = stratus_ingest::grib::decode_values(&bytes, i).unwrap();
        for (a, b) in f.values.iter().zip(&ecc[off..]) { worst = worst.max((a - b).abs()); }
        off += f.values.len();
        if i.index < 3 { println!("{} {} {:?} grid {:?}", i.short_name(), i.level_text(), i.valid_time(), f.grid); }
    }
    println!("{} messages, {} values, max |lead decode - eccodes| = {worst:e}", infos.len(), off);
    assert_eq!(off, ecc.len());
    for (name, _, b) in stratus_ingest::encode::fixtures::all() {
        let v = stratus_ingest::grib::scan(&b).and_then(|is| is.iter().map(|i| stratus_ingest::grib::decode_values(&b, i).map(|_| ())).collect::<Result<Vec<_>,_>>());
        println!("{name:>22} {:5} bytes: {}", b.len(), match v { Ok(_) => "OK".to_string(), Err(e) => e.to_string() });
    }
}
