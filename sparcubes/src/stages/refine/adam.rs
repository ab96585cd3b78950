//! Adam (Kingma & Ba, "Adam: A Method for Stochastic Optimization", ICLR 2015, Algorithm 1,
//! with its suggested β1 = 0.9, β2 = 0.999, ε = 1e-8) on the displacements, each component
//! kept within ±`bound` after every step.

/// Adam's moments for every active vertex.
pub struct Adam {
    m: Vec<[f64; 3]>,
    v: Vec<[f64; 3]>,
    t: i32,
}

const BETA1: f64 = 0.9;
const BETA2: f64 = 0.999;
const EPS: f64 = 1e-8;

impl Adam {
    /// Zero moments for `n` vertices.
    pub fn new(n: usize) -> Self {
        Self {
            m: vec![[0.0; 3]; n],
            v: vec![[0.0; 3]; n],
            t: 0,
        }
    }

    /// One step of size `rate` against `grad`, each component of `x` then clamped to
    /// ±`bound`. A component whose gradient has always been zero does not move.
    pub fn step(&mut self, x: &mut [[f64; 3]], grad: &[[f64; 3]], rate: f64, bound: f64) {
        self.t += 1;
        let c1 = 1.0 - BETA1.powi(self.t);
        let c2 = 1.0 - BETA2.powi(self.t);
        for ((x, g), (m, v)) in x
            .iter_mut()
            .zip(grad)
            .zip(self.m.iter_mut().zip(&mut self.v))
        {
            for a in 0..3 {
                m[a] = BETA1 * m[a] + (1.0 - BETA1) * g[a];
                v[a] = BETA2 * v[a] + (1.0 - BETA2) * g[a] * g[a];
                if m[a] == 0.0 {
                    continue;
                }
                let step = rate * (m[a] / c1) / ((v[a] / c2).sqrt() + EPS);
                x[a] = (x[a] - step).clamp(-bound, bound);
            }
        }
    }
}
