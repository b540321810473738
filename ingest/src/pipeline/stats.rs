//! The coverage statistics a sidecar records per layer: mean and maximum coverage over the
//! map's pixels, summed band by band as the rows stream past.

use crate::meta::CloudMapMeta;
use crate::sample::COVERAGE_FULL;

/// Running sums over the texels seen so far.
#[derive(Default)]
pub(super) struct Stats {
    sum: [f64; 3],
    max: [u16; 3],
    n: usize,
}

impl Stats {
    pub(super) fn add(&mut self, texels: &[[u16; 4]]) {
        for t in texels {
            for ((sum, max), &v) in self.sum.iter_mut().zip(&mut self.max).zip(t) {
                *sum += v as f64;
                *max = (*max).max(v);
            }
        }
        self.n += texels.len();
    }
    pub(super) fn apply(&self, meta: &mut CloudMapMeta) {
        for l in &mut meta.layers {
            let c = l.channel;
            l.mean_coverage = self.sum[c] / COVERAGE_FULL / self.n.max(1) as f64;
            l.max_coverage = self.max[c] as f64 / COVERAGE_FULL;
        }
    }
}

/// Fill `meta`'s layer statistics from a whole map's texels.
pub(crate) fn fill_stats(meta: &mut CloudMapMeta, texels: &[[u16; 4]]) {
    let mut s = Stats::default();
    s.add(texels);
    s.apply(meta);
}
