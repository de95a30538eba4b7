//! What the clients' default stage 1 sends and what that costs: ACUTS (its setting, stage 2 over
//! what stage 1 sent) with the repeat rule off and on, every error measured over every drawn
//! sample.

use super::*;

/// One stage-1 setting over a data set.
#[derive(Debug, Clone, Serialize)]
pub struct Stage1Row {
    pub stage1: String,
    /// Drawn samples.
    pub n: usize,
    /// Samples stage 1 sent to stage 2.
    pub sent: usize,
    /// Samples stage 2 retained.
    pub c: usize,
    pub ratio_at_bound: f64,
    /// Largest distance and pressure errors of a drawn sample against its retained segment.
    pub e_max: f64,
    pub p_max: f64,
}

/// ACUTS with `l_eps = resample` and `params`, its stage 1 keeping repeats and dropping them (the
/// clients' default); `optimal` holds optimal min-# per stroke at the bound.
pub(super) fn stage1_table(
    data_set: &DataSet,
    resample: f64,
    params: &AcutsParams,
    optimal: &[usize],
) -> Vec<Stage1Row> {
    let settings = [
        ("repeats kept", Resampler::new(resample).drop_repeats(false)),
        ("repeats dropped (default)", Resampler::new(resample)),
    ];
    settings
        .into_iter()
        .map(|(name, resampler)| {
            let mut row = Stage1Row {
                stage1: name.into(),
                n: 0,
                sent: 0,
                c: 0,
                ratio_at_bound: 0.0,
                e_max: 0.0,
                p_max: 0.0,
            };
            for samples in data_set.strokes() {
                let mut resampler = resampler.clone();
                let mut sent: Vec<usize> =
                    samples.iter().flat_map(|s| resampler.push(*s)).map(|(i, _)| i).collect();
                sent.extend(resampler.finish().map(|(index, _)| index));
                let kept: Vec<usize> = penmesh::simplify(&picked(samples, &sent), params)
                    .into_iter()
                    .map(|k| sent[k])
                    .collect();
                row.n += samples.len();
                row.sent += sent.len();
                row.c += kept.len();
                row.e_max = row.e_max.max(penmesh::e_max(samples, &kept));
                row.p_max = row.p_max.max(penmesh::p_max(samples, &kept));
            }
            row.ratio_at_bound = ratio(row.c, optimal.iter().sum());
            row
        })
        .collect()
}
