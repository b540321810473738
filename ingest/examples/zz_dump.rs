fn main() {
    for p in std::env::args().skip(1) {
        let b = std::fs::read(&p).unwrap();
        match stratus_ingest::grib::scan(&b) {
            Ok(ms) => {
                for m in ms {
                    println!("{m}");
                    println!(
                        "{:?} {:?} {} {}",
                        m.pressure_hpa(),
                        m.valid_time(),
                        m.short_name(),
                        m.is_relative_humidity()
                    );
                }
            }
            Err(e) => println!("ERR {e}"),
        }
    }
}
