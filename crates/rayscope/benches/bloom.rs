//! Bloom on an 800x800 image: the bright pass, the separable Gaussian and the add-back
//! (`rayscope::post::bloom::apply`), at the default radius (8 pixels) and a wide one (32).
//!
//! `cargo bench -p rayscope --bench bloom`.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rayscope::math::Color;
use rayscope::post::bloom;
use rayscope::settings::BloomSettings;

fn bench(c: &mut Criterion) {
    let (w, h) = (800u32, 800u32);
    // A dim image with a bright disc and scattered highlights: a fifth of the pixels glow.
    let pixels: Vec<Color> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 - 400.0, (i / w) as f32 - 400.0);
            let speck = (i.wrapping_mul(2_654_435_761) >> 24) % 97 == 0;
            if x * x + y * y < 160.0 * 160.0 || speck { Color::splat(4.0) } else { Color::splat(0.3) }
        })
        .collect();
    let mut g = c.benchmark_group("bloom_800x800");
    g.sample_size(20);
    g.throughput(Throughput::Elements(u64::from(w * h)));
    for radius in [8.0, 32.0] {
        let settings = BloomSettings { threshold: 1.0, radius, strength: 0.5 };
        g.bench_function(format!("radius_{radius}"), |b| {
            b.iter(|| {
                let mut image = pixels.clone();
                bloom::apply(black_box(&mut image), w, h, &settings);
                image
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
