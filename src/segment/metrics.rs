//! Overlap of two masks.

/// Dice's coefficient 2|A ∩ B| / (|A| + |B|) of two masks of the same length (nonzero
/// counts as inside); 1 when both are empty. `None` when the lengths differ.
pub fn dice(a: &[u8], b: &[u8]) -> Option<f64> {
    if a.len() != b.len() {
        return None;
    }
    let (mut both, mut na, mut nb) = (0u64, 0u64, 0u64);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (x != 0, y != 0);
        both += (x && y) as u64;
        na += x as u64;
        nb += y as u64;
    }
    Some(if na + nb == 0 { 1.0 } else { 2.0 * both as f64 / (na + nb) as f64 })
}

#[cfg(test)]
mod tests {
    #[test]
    fn dice_by_hand() {
        assert_eq!(super::dice(&[1, 1, 0, 0], &[1, 0, 1, 0]), Some(0.5));
        assert_eq!(super::dice(&[0, 0], &[0, 0]), Some(1.0));
        assert_eq!(super::dice(&[1, 2], &[3, 4]), Some(1.0));
        assert_eq!(super::dice(&[1], &[1, 0]), None);
    }
}
