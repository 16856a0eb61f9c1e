//! Pixel windows at image borders.
//!
//! Two policies, because the methods need different things: IDUW's public code *mirrors*
//! its window at borders (a border pixel sees reflected copies of its neighbours), while
//! neighbour selection *shifts* the search window inside the image, so that a border pixel
//! still has a full set of distinct candidates (duplicates would make covariance matrices
//! singular).

/// Reflects a coordinate into `0..n` without repeating the edge pixel (…, 2, 1, 0, 1, 2, …),
/// repeatedly if the window is wider than the image.
#[inline]
pub fn mirror(i: isize, n: usize) -> usize {
    if n == 1 {
        return 0;
    }
    let period = 2 * (n as isize - 1);
    let mut j = i.rem_euclid(period);
    if j >= n as isize {
        j = period - j;
    }
    j as usize
}

/// The `size`-wide range of coordinates around `c`, shifted to lie inside `0..n`
/// (truncated when the image is narrower than `size`).
#[inline]
pub fn shifted_range(c: usize, size: usize, n: usize) -> std::ops::Range<usize> {
    let len = size.min(n);
    let start = (c as isize - (size / 2) as isize).clamp(0, (n - len) as isize) as usize;
    start..start + len
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mirror_reflects_without_repeating_the_edge() {
        let got: Vec<usize> = (-4..9).map(|i| mirror(i, 5)).collect();
        assert_eq!(got, vec![4, 3, 2, 1, 0, 1, 2, 3, 4, 3, 2, 1, 0]);
        assert_eq!(mirror(-3, 2), 1);
        assert_eq!(mirror(7, 1), 0);
    }

    #[test]
    fn shifted_range_stays_inside() {
        assert_eq!(shifted_range(0, 5, 10), 0..5);
        assert_eq!(shifted_range(5, 5, 10), 3..8);
        assert_eq!(shifted_range(9, 5, 10), 5..10);
        assert_eq!(shifted_range(1, 11, 4), 0..4);
    }
}
