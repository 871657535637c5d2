//! Input validation shared by every constructor: finite numbers, symmetric positive-definite
//! matrices, slices of the right length.

use crate::error::{Error, Quantity};
use crate::{Real, real};
use nalgebra::{SMatrix, SVector};

/// A control period or step length: finite (`NonFinite(Period)`) and strictly positive
/// (`NotPositive(Period)`).
pub fn period<T: Real>(period: T) -> Result<(), Error> {
    if !period.is_finite() {
        return Err(Error::NonFinite(Quantity::Period));
    }
    if period <= T::zero() {
        return Err(Error::NotPositive(Quantity::Period));
    }
    Ok(())
}

/// `Ok` when every entry is finite, `Err(NonFinite(quantity))` otherwise.
///
/// One pass of additions first: a NaN or an infinity anywhere makes the sum non-finite, so a
/// finite sum proves every entry finite (the cycle's usual case, without a branch per entry);
/// only a non-finite sum is looked at entry by entry (finite entries may overflow it).
#[inline]
pub fn finite<T: Real, const R: usize, const C: usize>(
    quantity: Quantity,
    m: &SMatrix<T, R, C>,
) -> Result<(), Error> {
    if sum(m).is_finite() || m.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::NonFinite(quantity))
    }
}

/// The sum of `m`'s entries: finite only if every entry is (a NaN or an infinity makes it
/// non-finite), which lets a caller check several matrices with one comparison and look at
/// them one by one only when it fails.
#[inline]
pub fn sum<T: Real, const R: usize, const C: usize>(m: &SMatrix<T, R, C>) -> T {
    let mut total = T::zero();
    for x in m.iter() {
        total += *x;
    }
    total
}

/// Checks that `m` is finite, symmetric (to rounding) and positive definite, and returns its
/// inverse (via Cholesky).
pub fn spd_inverse<T: Real, const D: usize>(
    quantity: Quantity,
    m: &SMatrix<T, D, D>,
) -> Result<SMatrix<T, D, D>, Error> {
    finite(quantity, m)?;
    let scale = m.amax();
    let tol = T::default_epsilon() * real(16.0) * scale;
    for i in 0..D {
        for j in 0..i {
            if (m[(i, j)] - m[(j, i)]).abs() > tol {
                return Err(Error::NotSymmetric(quantity));
            }
        }
    }
    match nalgebra::Cholesky::new(*m) {
        Some(ch) => {
            let inv = ch.inverse();
            finite(quantity, &inv).map_err(|_| Error::NotPositiveDefinite(quantity))?;
            Ok(inv)
        }
        None => Err(Error::NotPositiveDefinite(quantity)),
    }
}

/// Reads an R×C matrix from `R·C` row-major entries.
pub fn matrix_from_row_major<T: Real, const R: usize, const C: usize>(
    quantity: Quantity,
    data: &[T],
) -> Result<SMatrix<T, R, C>, Error> {
    if data.len() != R * C {
        return Err(Error::WrongShape {
            quantity,
            expected: R * C,
            found: data.len(),
        });
    }
    let m = SMatrix::<T, R, C>::from_fn(|i, j| data[i * C + j]);
    finite(quantity, &m)?;
    Ok(m)
}

/// Reads a vector of exactly `D` entries.
pub fn vector_from_slice<T: Real, const D: usize>(
    quantity: Quantity,
    data: &[T],
) -> Result<SVector<T, D>, Error> {
    matrix_from_row_major::<T, D, 1>(quantity, data)
}

/// Reads a gain: one entry means that multiple of the identity, `D·D` entries a row-major
/// matrix. The result is checked symmetric positive definite.
pub fn gain_from_slice<T: Real, const D: usize>(
    quantity: Quantity,
    data: &[T],
) -> Result<SMatrix<T, D, D>, Error> {
    let m = if data.len() == 1 {
        SMatrix::<T, D, D>::identity() * data[0]
    } else if data.len() == D * D {
        matrix_from_row_major::<T, D, D>(quantity, data)?
    } else {
        return Err(Error::WrongShape {
            quantity,
            expected: D * D,
            found: data.len(),
        });
    };
    spd_inverse(quantity, &m)?;
    Ok(m)
}
