use isoline::reconstruct::{reconstruct_warm, Params};
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let truth: isoline::format::TruthFile = serde_json::from_str(&std::fs::read_to_string(std::env::args().nth(2).unwrap()).unwrap()).unwrap();
    let frames = isoline::ingest::read_frames(std::path::Path::new(&path)).unwrap();
    let p = Params::default();
    for warm in [false, true] {
        let mut prev = None;
        let (mut its, mut ms, mut worst, mut warmed) = (Vec::new(), Vec::new(), 0.0f64, 0);
        for f in &frames {
            let r = reconstruct_warm(&f.points, &p, if warm { prev.as_ref() } else { None }).unwrap();
            let a = isoline::eval::compare(&r.polylines, &truth.for_frame(Some(f.frame)), None);
            worst = worst.max(a.hausdorff.unwrap_or(f64::NAN));
            its.push(r.stats.iterations);
            ms.push(r.stats.ms.total);
            warmed += r.stats.warm_start as usize;
            prev = Some(r);
        }
        its.sort();
        ms.sort_by(f64::total_cmp);
        println!("warm={warm}: median iterations {} median ms {:.0} worst hausdorff {:.2e} warm frames {warmed}/{}", its[its.len() / 2], ms[ms.len() / 2], worst, frames.len());
    }
}
