//! Criterion benchmarks: every early-vision stage and the whole chain, CPU
//! and GPU side by side, at 256×242, 640×480 and 1280×720.
//! Ids: `<stage>/cpu/<WxH>` and `<stage>/gpu/<WxH>`; throughput in pixels
//! (a GPU iteration processes several frames; its throughput says so).
//! `pipetrack bench` prints the same comparison as GPU/CPU ratios.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use pipetrack::GpuContext;
use pipetrack::cli::bench::{Inputs, cpu_body, cpu_frames_per_call, gpu_body, gpu_frames_per_call, stages};

const SIZES: &[(usize, usize)] = &[(256, 242), (640, 480), (1280, 720)];

fn early_vision(c: &mut Criterion) {
    let gpu = match GpuContext::new() {
        Ok(ctx) => {
            eprintln!("GPU: {}", ctx.adapter_name());
            Some(ctx)
        }
        Err(e) => {
            eprintln!("no GPU adapter ({e}): GPU benchmarks skipped");
            None
        }
    };
    for &(w, h) in SIZES {
        let inp = Inputs::new(w, h).expect("bench inputs");
        let size = format!("{w}x{h}");
        for stage in stages() {
            let mut group = c.benchmark_group(stage);
            group.sample_size(10);
            group.throughput(Throughput::Elements((w * h * cpu_frames_per_call(stage)) as u64));
            let mut body = cpu_body(stage, &inp).expect("cpu body");
            group.bench_function(BenchmarkId::new("cpu", &size), |b| b.iter(|| body().expect("cpu stage")));
            drop(body);
            if let Some(ctx) = &gpu {
                group.throughput(Throughput::Elements((w * h * gpu_frames_per_call(stage)) as u64));
                let mut body = gpu_body(stage, ctx, &inp).expect("gpu body");
                group.bench_function(BenchmarkId::new("gpu", &size), |b| b.iter(|| body().expect("gpu stage")));
            }
            group.finish();
        }
    }
}

criterion_group!(benches, early_vision);
criterion_main!(benches);
