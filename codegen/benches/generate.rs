//! Criterion benchmark of code generation: the whole model source (symbolic build,
//! differentiation, CSE, emission, prettyplease) for chains of 1, 2, 4 and 8 hexagonal modules.
//!
//! Run with `cargo bench -p softcbf-codegen --bench generate`. Compile time of the emitted
//! source is measured separately by `scripts/measure-scaling`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use softcbf_codegen::generate;
use softcbf_description::robot::{Routing, Structure};

fn bench_generate(c: &mut Criterion) {
    let mut group = c.benchmark_group("generate");
    // One generation of 8 modules takes a fraction of a second: ten samples suffice.
    group.sample_size(10);
    for n in [1usize, 2, 4, 8] {
        let structure = Structure::new(vec![6; n], vec![3; n], Routing::Local);
        group.bench_function(format!("{n}_modules"), |bench| {
            bench.iter(|| {
                generate(black_box(&structure), "the benchmark structure")
                    .text
                    .len()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_generate);
criterion_main!(benches);
