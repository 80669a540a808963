fn main() {
    let data = neus::Dataset::load(std::path::Path::new("/tmp/w/tt_small/background")).unwrap();
    let cfg = neus::TrainConfig::preset("fast", neus::CaptureSubject::Scene).unwrap();
    let mut t = neus::NeusTrainer::new(cfg, data).unwrap();
    let s = t.field.sdf_values(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.5], 4);
    println!("sdf {s:?} centre {:?} r {}", t.data.centre, t.data.radius);
    let b = t.field.background.as_ref().unwrap();
    println!("bg params finite {}", b.density_params.iter().all(|v| v.is_finite()));
    for i in 0..400 {
        if i == 36000 {
            let b = t.field.background.as_ref().unwrap();
            let mut sc = neus::background_field::BackgroundScratch::default();
            for v in 0..t.data.views.len() {
                let (mut o, mut d) = (vec![], vec![]);
                for y in 0..t.data.height { for x in 0..t.data.width {
                    let r = t.data.ray(v, x as f64 + 0.5, y as f64 + 0.5);
                    o.push(r.origin); d.push(r.dir);
                }}
                b.forward(&o, &d, |_| 0.999, [0.5; 3], &mut sc);
                for (k, c) in sc.out.iter().enumerate() {
                    if !c[0].is_finite() { println!("view {v} px {k} o {:?} d {:?} -> {:?}", o[k], d[k], c); break; }
                }
            }
        }
        let st = t.step();
        let b = t.field.background.as_ref().unwrap();
        let fin = |v: &Vec<f32>| v.iter().all(|x| x.is_finite());
        println!("{i} grid {} dens {} col {} | sdf {} fgrid {} col {} extra {:?}", fin(&b.grid_params), fin(&b.density_params), fin(&b.color_params), fin(&t.field.sdf_params), fin(&t.field.grid_params), fin(&t.field.color_params), t.field.extra);
        if i % 5 == 0 || !st.loss.rgb.is_finite() { println!("{i} {st:?}"); } if !st.loss.rgb.is_finite() { break; }
    }
}
