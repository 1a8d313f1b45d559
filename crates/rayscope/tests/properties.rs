//! Properties over arbitrary inputs (proptest): the sampler's numbers stay in their ranges for
//! any seed, pixel, sample index and count; and the film holds the same bits however the
//! renderer splits a pixel's samples into passes, threads and interruptions.

use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, Ordering};

use proptest::prelude::*;
use rayscope::camera::CameraMotion;
use rayscope::film::Film;
use rayscope::math::{Color, Vec2, Vec3A};
use rayscope::render::{RenderProgress, SamplePass, render_pass};
use rayscope::sampler::{Pcg32, PixelSampler, Strata2, stratum_1d, stratum_2d};
use rayscope::scene::{LoadContext, Scene, builtin};
use rayscope::settings::{MAX_SAMPLES, RenderSettings};

/// Whether `x` is in `[0, 1)`.
fn in_unit(x: f32) -> bool {
    (0.0..1.0).contains(&x)
}

/// Whether `x` is in `[0, 1]`: the stratified helpers' range. Their top stratum's largest
/// jitter, `1 - 2^-24`, rounds `(n - 1) + jitter` up to `n` in f32, so the value is exactly 1
/// there (about once in 2^24 draws in that stratum). Every consumer accepts 1: light points
/// are defined over `[0,1]^2`, and the pixel filters' warps at 1 give the filter's edge.
/// Clamping it would change image bits, so the range is documented, not changed.
fn in_closed_unit(x: f32) -> bool {
    (0.0..=1.0).contains(&x)
}

/// A jitter as `next_f32` draws it (a multiple of 2^-24 below 1), with its largest value drawn
/// often: uniform draws would almost never reach the edge.
fn jitter() -> impl Strategy<Value = f32> {
    let top = (1u32 << 24) - 1;
    prop_oneof![0..=top, Just(top), Just(0)].prop_map(|b| b as f32 / (1u32 << 24) as f32)
}

/// A sample count: small ones, perfect squares (the jittered grid), and any up to the limit.
fn count() -> impl Strategy<Value = u32> {
    prop_oneof![1..=64u32, (1..=256u32).prop_map(|m| m * m), 1..=MAX_SAMPLES]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// PCG32's floats are in `[0, 1)` on every stream, from every state.
    #[test]
    fn pcg_values_are_in_the_unit_interval(state in any::<u64>(), stream in any::<u64>(), n in 1..64usize) {
        let mut rng = Pcg32::from_state(state, stream);
        let mut seeded = Pcg32::new(state, stream);
        for _ in 0..n {
            prop_assert!(in_unit(rng.next_f32()));
            let v = seeded.next_2d();
            prop_assert!(in_unit(v.x) && in_unit(v.y), "{v:?}");
        }
    }

    /// A pixel sample's shutter time and its stream of numbers are in `[0, 1)`, and its
    /// position in the pixel in `[0, 1]^2` (`[0, 1)^2` off the jittered grid), for any seed,
    /// pixel, sample index and planned count (0: open-ended).
    #[test]
    fn pixel_sampler_values_are_in_range(
        seed in any::<u64>(),
        pixel in any::<u32>(),
        index in prop_oneof![0..1024u32, any::<u32>()],
        planned in prop_oneof![Just(0u32), Just(1), count(), any::<u32>()],
        draws in 0..16usize,
    ) {
        let mut s = PixelSampler::new(seed, pixel, index, planned);
        prop_assert!(in_unit(s.time), "time {}", s.time);
        let o = s.pixel_offset;
        prop_assert!(in_closed_unit(o.x) && in_closed_unit(o.y), "offset {o:?}");
        let on_grid = rayscope::sampler::exact_sqrt(planned).is_some_and(|m| m > 1) && index < planned;
        if !on_grid {
            prop_assert!(in_unit(o.x) && in_unit(o.y), "offset {o:?} off the grid");
        }
        for _ in 0..draws {
            prop_assert!(in_unit(s.next_f32()));
            let v = s.next_2d();
            prop_assert!(in_unit(v.x) && in_unit(v.y), "{v:?}");
        }
    }

    /// Stratified samples stay in `[0, 1]` and in their own stratum (up to the rounding of
    /// its upper edge), for any count and any jitter `next_f32` can draw.
    #[test]
    fn stratified_values_are_in_range(n in count(), i in any::<u32>(), jx in jitter(), jy in jitter()) {
        let i = i % n;
        let x = stratum_1d(i, n, jx);
        prop_assert!(in_closed_unit(x), "1D sample {i} of {n}: {x}");
        prop_assert!(x >= i as f32 / n as f32 && x <= (i + 1) as f32 / n as f32, "1D sample {i} of {n}: {x}");
        let v = Strata2::new(n).sample(i, Vec2::new(jx, jy));
        prop_assert!(in_closed_unit(v.x) && in_closed_unit(v.y), "2D sample {i} of {n}: {v:?}");
        prop_assert_eq!(v, stratum_2d(i, n, Vec2::new(jx, jy)));
    }
}

/// The edge case behind [`in_closed_unit`], pinned so that the documented range stays true.
#[test]
fn the_top_stratum_reaches_one_at_the_largest_jitter() {
    let largest = ((1u32 << 24) - 1) as f32 / (1u32 << 24) as f32;
    assert!(largest < 1.0);
    assert_eq!(stratum_1d(1, 2, largest), 1.0);
    assert_eq!(Strata2::new(9).sample(8, Vec2::splat(largest)), Vec2::ONE);
}

/// The scene the film properties render: soft shadows from a sphere light (grouped shadow
/// rays), mirror and glossy reflection, so every kind of ray adds to the film.
fn scene() -> &'static Scene {
    static SCENE: OnceLock<Scene> = OnceLock::new();
    SCENE.get_or_init(|| {
        let desc = builtin::scene_desc("cornell-box-sphere-light").unwrap();
        Scene::from_desc(&desc, &LoadContext::default()).unwrap()
    })
}

/// Small, but three bands of rows tall, so that a pass can stop after the first band.
fn settings(spp: u32) -> RenderSettings {
    RenderSettings { width: 9, height: 40, spp, light_samples: 4, gloss_samples: 2, ..RenderSettings::default() }
}

/// The camera: still (camera rays in packets) or moving (pixel by pixel).
fn camera(moving: bool) -> CameraMotion {
    let mut c = scene().camera_motion();
    if moving {
        let mut end = c.start;
        end.position += Vec3A::X * 0.05;
        c.end = Some(end);
    }
    c
}

/// One pass of `samples` samples towards `planned` on `threads` threads; with `interrupt`,
/// it stops after the first band of rows (on one thread, the others are then never started).
fn pass(film: &mut Film, camera: &CameraMotion, planned: u32, samples: u32, threads: usize, interrupt: bool) {
    let s = settings(planned);
    let pass = SamplePass { samples, limit: planned, planned, seed: 7 };
    let threads = if interrupt { 1 } else { threads };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let cancel = AtomicBool::new(false);
    let stop = |_: RenderProgress| {
        if interrupt {
            cancel.store(true, Ordering::Relaxed);
        }
    };
    pool.install(|| render_pass(scene(), &s, camera, film, pass, &cancel, &stop));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// The renderer adds each pixel's samples in sample order, each with its own random
    /// numbers, so the film is the same, bit for bit, however the samples are split into
    /// passes, on however many threads, with passes interrupted and caught up (the ones
    /// behind get the samples the others already have, and no pixel goes past the plan).
    #[test]
    fn any_split_of_the_samples_gives_the_same_film(
        planned in 1..=9u32,
        passes in prop::collection::vec((1..=4u32, 1..=2usize, any::<bool>()), 1..6),
        moving in any::<bool>(),
    ) {
        let camera = camera(moving);
        let mut one_shot = Film::new(9, 40);
        pass(&mut one_shot, &camera, planned, planned, 2, false);
        prop_assert!(one_shot.mean().max_element() > 0.0, "the view shows the lit box");
        let mut film = Film::new(9, 40);
        for &(samples, threads, interrupt) in &passes {
            pass(&mut film, &camera, planned, samples, threads, interrupt);
        }
        // Then passes until every pixel has its samples.
        while film.sample_range().0 < planned {
            pass(&mut film, &camera, planned, 1, 2, false);
        }
        prop_assert_eq!(film.sample_range(), (planned, planned));
        prop_assert!(film == one_shot, "the split {:?} changed the film", passes);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// The film's sums are exact: a pixel's samples added in another order, or merged from
    /// films of some of them, give the same value, bit for bit. (What lets a render be split
    /// into parts on many machines and merged, or stopped and resumed.)
    #[test]
    fn another_order_of_the_samples_gives_the_same_bits(
        values in prop::collection::vec((0.0..4.0f32, 0.0..4.0f32, -1e9..1e9f32), 1..64),
        shift in any::<usize>(),
    ) {
        let colors: Vec<Color> = values.iter().map(|&(r, g, b)| Color::new(r, g, b)).collect();
        let add = |order: &mut dyn Iterator<Item = Color>| {
            let mut film = Film::new(1, 1);
            for c in order {
                film.add(0, 0, c);
            }
            film.get(0, 0)
        };
        let in_order = add(&mut colors.iter().copied());
        let k = shift % colors.len();
        let rotated = add(&mut colors[k..].iter().chain(&colors[..k]).copied());
        let reversed = add(&mut colors.iter().rev().copied());
        for other in [rotated, reversed] {
            prop_assert_eq!(other, in_order);
        }
    }
}
