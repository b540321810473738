use stratus_ingest::forecast::{Forecast, LevelSelect, DEFAULT_TOP_HPA};
use stratus_ingest::pipeline::{IngestOptions, Plan};
use stratus_ingest::spline::Interp;
use stratus_ingest::Region;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let out = std::path::Path::new(&a[1]);
    std::fs::create_dir_all(out).unwrap();
    for (k, f) in [
        "/work/shared/data/gfs/gfs.t12z.pgrbf120.2p5deg.grib2",
        "/work/shared/data/gfs-series/gfs.t18z.pgrb2.2p50.f006",
    ]
    .iter()
    .enumerate()
    {
        let fc = Forecast::open(
            std::path::Path::new(f),
            LevelSelect::AllBelow(DEFAULT_TOP_HPA),
        )
        .unwrap();
        let plan = Plan::new(
            &fc,
            &IngestOptions {
                region: Region::parse("0,55,39,105").unwrap(),
                width: 260,
                height: 220,
                rh_cr: [0.8, 0.65, 0.8],
                interp: Interp::Spline,
            },
        )
        .unwrap();
        plan.write(&out.join(format!("m{k}.png")), &|_| {}).unwrap();
        let map = plan.build();
        map.save(&out.join(format!("s{k}.png"))).unwrap();
    }
}
