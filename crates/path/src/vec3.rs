//! A point or direction in machine coordinates (X, Y, Z) \[mm\].

use std::ops::{Add, AddAssign, Index, IndexMut, Mul, Neg, Sub};

/// Three coordinates X, Y, Z \[mm\] (or a direction, a velocity \[mm/s\], …).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Vec3(pub [f64; 3]);

impl Vec3 {
    /// The origin.
    pub const ZERO: Vec3 = Vec3([0.0; 3]);

    /// (x, y, z).
    pub const fn new(x: f64, y: f64, z: f64) -> Self {
        Vec3([x, y, z])
    }

    /// The unit vector along coordinate `i` (0 = X, 1 = Y, 2 = Z).
    pub fn axis(i: usize) -> Self {
        let mut v = Vec3::ZERO;
        v.0[i] = 1.0;
        v
    }

    /// Dot product.
    pub fn dot(self, o: Vec3) -> f64 {
        self.0[0] * o.0[0] + self.0[1] * o.0[1] + self.0[2] * o.0[2]
    }

    /// Cross product.
    pub fn cross(self, o: Vec3) -> Vec3 {
        let [a, b, c] = self.0;
        let [x, y, z] = o.0;
        Vec3([b * z - c * y, c * x - a * z, a * y - b * x])
    }

    /// Euclidean length.
    pub fn norm(self) -> f64 {
        self.dot(self).sqrt()
    }

    /// This vector scaled to length 1 (the zero vector stays zero).
    pub fn unit(self) -> Vec3 {
        let n = self.norm();
        if n > 0.0 { self * (1.0 / n) } else { self }
    }

    /// Each coordinate's absolute value.
    pub fn abs(self) -> Vec3 {
        Vec3(self.0.map(f64::abs))
    }

    /// Coordinate-wise maximum.
    pub fn max(self, o: Vec3) -> Vec3 {
        Vec3([
            self.0[0].max(o.0[0]),
            self.0[1].max(o.0[1]),
            self.0[2].max(o.0[2]),
        ])
    }

    /// Coordinate-wise minimum.
    pub fn min(self, o: Vec3) -> Vec3 {
        Vec3([
            self.0[0].min(o.0[0]),
            self.0[1].min(o.0[1]),
            self.0[2].min(o.0[2]),
        ])
    }

    /// Whether every coordinate is finite.
    pub fn is_finite(self) -> bool {
        self.0.iter().all(|v| v.is_finite())
    }
}

impl Add for Vec3 {
    type Output = Vec3;
    fn add(self, o: Vec3) -> Vec3 {
        Vec3([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
}

impl AddAssign for Vec3 {
    fn add_assign(&mut self, o: Vec3) {
        *self = *self + o;
    }
}

impl Sub for Vec3 {
    type Output = Vec3;
    fn sub(self, o: Vec3) -> Vec3 {
        Vec3([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
}

impl Mul<f64> for Vec3 {
    type Output = Vec3;
    fn mul(self, k: f64) -> Vec3 {
        Vec3(self.0.map(|v| v * k))
    }
}

impl Neg for Vec3 {
    type Output = Vec3;
    fn neg(self) -> Vec3 {
        self * -1.0
    }
}

impl Index<usize> for Vec3 {
    type Output = f64;
    fn index(&self, i: usize) -> &f64 {
        &self.0[i]
    }
}

impl IndexMut<usize> for Vec3 {
    fn index_mut(&mut self, i: usize) -> &mut f64 {
        &mut self.0[i]
    }
}
