//! One spectrum sample of the [000] scenario (36 bands, 400–750 nm, physical materials, cube
//! body): geometry, facet flux for every band, noise. Run: `cargo bench --bench spectrum`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use glint_sensor::spectra_scene::SpectraScene;
use shared_types::Scenario;

fn bench(c: &mut Criterion) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/geo-hover-yspin.toml"
    );
    let mut sc = Scenario::from_file(std::path::Path::new(path)).expect("scenario");
    let spectra = sc.spectra.as_mut().expect("spectra section");
    spectra.snr = Some(10.0);
    let scene = SpectraScene::new(spectra, 1).expect("scene");
    let n = scene.len();
    let mut k = 0u64;
    c.bench_function("spectrum/sample_36_bands", |b| {
        b.iter(|| {
            k = (k + 1) % n;
            black_box(scene.sample(black_box(k)).expect("sample"))
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_secs(1));
    targets = bench
}
criterion_main!(benches);
