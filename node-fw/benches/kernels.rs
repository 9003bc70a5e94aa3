//! Host cost of the two kernels: one digital-line step, one ray/sphere test.
//!
//! `cargo bench -p node-fw --bench kernels`; criterion reports time per element.

// criterion_group! generates an undocumented public function.
#![allow(missing_docs)]

use criterion::{BenchmarkId, Criterion, Throughput, black_box, criterion_group, criterion_main};
use fixed::types::I16F16;
use node_fw::{DigitalLine, Direction, Grid, Line, Material, Point, Sphere};

fn raw(x: f64) -> i32 {
    (x * 65536.0).round() as i32
}

fn line(o: [f64; 3], d: [i64; 3]) -> Line {
    Line::new(Point::from_bits(o.map(raw)).unwrap(), Direction::normalize(d).unwrap())
}

/// Cube steps along directions with one, two and three moving axes.
fn cube_step(c: &mut Criterion) {
    let grid = Grid::new([256; 3]).unwrap();
    let mut group = c.benchmark_group("cube_step");
    let cases = [
        ("axis", line([0.5, 0.5, 0.5], [1, 0, 0])),
        ("diagonal", line([0.5, 0.7, 0.3], [1_000_000, 618_034, 381_966])),
        ("far_eye", line([-9000.0, -4000.0, -3000.0], [1_000_000, 470_000, 340_000])),
    ];
    for (name, l) in cases {
        let steps = {
            let mut w = DigitalLine::enter(&l, &grid).unwrap();
            let mut n = 0u64;
            while grid.contains(w.cell()) {
                w.step();
                n += 1;
            }
            n
        };
        group.throughput(Throughput::Elements(steps));
        group.bench_with_input(BenchmarkId::from_parameter(name), &l, |b, l| {
            b.iter(|| {
                let mut w = DigitalLine::enter(black_box(l), &grid).unwrap();
                while grid.contains(w.cell()) {
                    w.step();
                }
                w.cell()
            })
        });
    }
    group.finish();
}

/// Ray/sphere tests: mostly misses (the common case in a cube list), and hits.
fn sphere_test(c: &mut Criterion) {
    let grid = Grid::new([256; 3]).unwrap();
    let mut spheres = Vec::new();
    let mut seed = 12345u64;
    let mut next = move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for id in 0..1024u16 {
        let c = [next() * 256.0, next() * 256.0, next() * 256.0];
        let r = 0.05 + next() * 2.0;
        let s = Sphere::new(
            id,
            Point::from_bits(c.map(raw)).unwrap(),
            I16F16::from_num(r),
            Material::default(),
            &grid,
        );
        spheres.push(s.unwrap());
    }
    let mut group = c.benchmark_group("sphere_test");
    group.throughput(Throughput::Elements(spheres.len() as u64));
    let miss = line([-100.0, 128.0, 128.0], [1_000_000, 1_234, -987]);
    group.bench_function("mixed", |b| {
        b.iter(|| spheres.iter().filter_map(|s| s.intersect(black_box(&miss))).count())
    });
    let hits: Vec<(Line, Sphere)> = spheres
        .iter()
        .map(|s| {
            let c = s.center().map(|v| v as f64 / 65536.0);
            (line([c[0] - 50.0, c[1] - 20.0, c[2] + 10.0], [50_000, 20_000, -10_000]), *s)
        })
        .collect();
    group.bench_function("hit", |b| {
        b.iter(|| hits.iter().filter_map(|(l, s)| s.intersect(black_box(l))).count())
    });
    group.finish();
}

criterion_group!(benches, cube_step, sphere_test);
criterion_main!(benches);
