//! Encode and decode of a binary `Points` frame of 32 samples, in samples per second.
//!
//! `cargo bench -p penmesh --bench codec`

#[path = "support/cpu_time.rs"]
mod cpu_time;

use cpu_time::ThreadCpuTime;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use penmesh::Sample;
use penmesh::protocol::{
    ClientMessage, MAX_FRAME_BYTES_DEFAULT, PointBatch, Points, decode_client, encode_client,
    quantize_sample,
};
use std::hint::black_box;

/// 32 samples of a smooth pen stroke at 100 Hz, in tablet units.
fn points_frame() -> ClientMessage {
    let samples = (0..32)
        .map(|i| {
            let f = f64::from(i);
            quantize_sample(&Sample::new(
                5000.0 + 40.0 * f + 30.0 * (f * 0.2).sin(),
                3000.0 + 25.0 * (f * 0.15).cos() * f,
                10.0 * f + 420.0,
                0.55 + 0.3 * (f * 0.1).sin(),
            ))
        })
        .collect();
    ClientMessage::Points(Points {
        stroke: uuid::Uuid::from_u128(0x67e5_5044_10b1_426f_9247_bb68_0e5f_e0c8),
        seq: 42,
        points: PointBatch(samples),
    })
}

fn codec(c: &mut Criterion<ThreadCpuTime>) {
    let msg = points_frame();
    let frame = encode_client(&msg);
    let mut group = c.benchmark_group("codec_points_32");
    group.throughput(Throughput::Elements(32));
    group.bench_function("encode", |b| b.iter(|| encode_client(black_box(&msg))));
    group.bench_function("decode", |b| {
        b.iter(|| decode_client(black_box(&frame), MAX_FRAME_BYTES_DEFAULT).unwrap())
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(ThreadCpuTime);
    targets = codec
}
criterion_main!(benches);
