//! Element groups: several candidates that are one physical part.
//!
//! A cam's potential V(x) = Σⱼ cⱼ Bⱼ(x) enters the fit as one column per basis function and sign
//! (+Bⱼ and −Bⱼ, each with k ≥ 0, so cⱼ = k⁺ⱼ − k⁻ⱼ), but it is built as one part on one
//! follower spring. What makes those columns one part is said here, once, from the elements'
//! profiles; everything downstream sees only a [`Group`]:
//!
//! - the selection counts a group as one item for `max_elements`;
//! - a build draws one rate deviation δ per group (its spring's rate scales the whole part), and
//!   the tolerance-aware fit models it so (one block per group);
//! - the solvers may merge each (+, −) pair into one signed unknown, and pin one coefficient when
//!   the whole part is in play and a uniform shift of its coefficients changes nothing
//!   ([`Group::uniform_gauge`]: Σⱼ Bⱼ = 1 for a cam);
//! - its smoothing penalty is a set of rows over its signed coefficients
//!   ([`Group::roughness_rows`]);
//! - the bill of materials gives it one row, its members' rows named `C01.07+` (prefix, group,
//!   coefficient, sign).
//!
//! A later part of the same kind (a linkage, a profiled leaf spring) adds a [`Shape`] and its
//! profile's [`Profile::member`]; the fit needs no change.

use super::catalog::Candidate;
use super::spline::Knots;
use super::{Element, Profile};

/// What a part looks like, as far as grouping needs to know: the same for all its members.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Shape {
    /// A cam: cubic B-spline coefficients on `count` uniform knots spaced `width` (as bits).
    Cam {
        /// Number of knots N (the cam has N + 2 coefficients).
        count: u16,
        /// Knot spacing h in rad, as `f64::to_bits`.
        width_bits: u64,
    },
}

impl Shape {
    /// How many signed coefficients the part has.
    pub fn coefficients(self) -> usize {
        match self {
            Shape::Cam { count, .. } => usize::from(count) + 2,
        }
    }

    /// The letter of its ids in the bill of materials (`C01`).
    pub fn prefix(self) -> &'static str {
        match self {
            Shape::Cam { .. } => "C",
        }
    }

    /// Whether adding one value to every signed coefficient changes no torque (then the
    /// potentials of the part have a free constant, which the solvers fix).
    pub fn uniform_gauge(self) -> bool {
        match self {
            // Σⱼ Bⱼ = 1 everywhere: a constant added to every cⱼ adds a constant to V.
            Shape::Cam { .. } => true,
        }
    }

    /// Rows D over the signed coefficients with ‖D c‖² the part's roughness: for a cam
    /// ∫ V‴(x)² dx over the knot span (the torque's curvature). `offset` is the members' x₀.
    pub fn roughness_rows(self, offset: f64) -> Vec<Vec<f64>> {
        match self {
            Shape::Cam { count, width_bits } => {
                Knots { lo: offset, width: f64::from_bits(width_bits), count }.third_derivative_rows()
            }
        }
    }
}

/// What makes an element one coefficient of a part.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Member {
    /// The part's shape.
    pub shape: Shape,
    /// Which of its signed coefficients this column carries.
    pub coefficient: u16,
    /// The column carries −1 × the coefficient's function (the − half of a ± pair).
    pub negative: bool,
}

impl Profile {
    /// The part this profile's element is one coefficient of; None for an element that is a part
    /// of its own (every spring).
    pub fn member(self) -> Option<Member> {
        match self {
            Profile::Spline(b) => Some(Member {
                shape: Shape::Cam { count: b.count, width_bits: b.width_bits },
                coefficient: b.index,
                negative: b.negative,
            }),
            _ => None,
        }
    }
}

/// The fit's columns: the candidates and which of them are one part.
pub type Columns<'a> = (&'a [Candidate], &'a Grouping);

/// Several columns that are one part.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// Its shape.
    pub shape: Shape,
    /// Its columns (indices into the elements grouped), ascending.
    pub columns: Vec<usize>,
    /// Per signed coefficient, the column of its + and of its − half (None where absent).
    pub pairs: Vec<(Option<usize>, Option<usize>)>,
    /// The members' offset x₀ (a cam: its first knot).
    pub offset: f64,
}

impl Group {
    /// Whether a uniform shift of the coefficients changes nothing (see [`Shape::uniform_gauge`]).
    pub fn uniform_gauge(&self) -> bool {
        self.shape.uniform_gauge()
    }

    /// The smoothing rows over the group's signed coefficients (see [`Shape::roughness_rows`]).
    pub fn roughness_rows(&self) -> Vec<Vec<f64>> {
        self.shape.roughness_rows(self.offset)
    }

    /// The id of the group numbered `number` (from 0) in a bill of materials: `C01`.
    pub fn id(&self, number: usize) -> String {
        format!("{}{:02}", self.shape.prefix(), number + 1)
    }
}

/// The elements grouped into parts: which group each element belongs to (None: a part of its
/// own) and the groups, numbered in order of their first element.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Grouping {
    /// Per element, its group.
    pub of: Vec<Option<usize>>,
    /// The groups.
    pub groups: Vec<Group>,
}

impl Grouping {
    /// Groups `elements`, each with a key of the family it comes from: members of one family on
    /// one coupling with one shape are one part.
    pub fn new<'a, K: PartialEq + 'a>(elements: impl IntoIterator<Item = (K, &'a Element)>) -> Grouping {
        let mut keys: Vec<(K, Vec<u64>, Shape)> = Vec::new();
        let mut out = Grouping::default();
        for (j, (family, e)) in elements.into_iter().enumerate() {
            let Some(m) = e.profile.member() else {
                out.of.push(None);
                continue;
            };
            let coupling: Vec<u64> = e.coupling.iter().map(|a| a.to_bits()).collect();
            let g = match keys.iter().position(|(f, a, s)| *f == family && *a == coupling && *s == m.shape) {
                Some(g) => g,
                None => {
                    keys.push((family, coupling, m.shape));
                    out.groups.push(Group {
                        shape: m.shape,
                        columns: Vec::new(),
                        pairs: vec![(None, None); m.shape.coefficients()],
                        offset: e.offset,
                    });
                    out.groups.len() - 1
                }
            };
            let group = &mut out.groups[g];
            group.columns.push(j);
            if let Some(pair) = group.pairs.get_mut(usize::from(m.coefficient)) {
                if m.negative {
                    pair.1.get_or_insert(j);
                } else {
                    pair.0.get_or_insert(j);
                }
            }
            out.of.push(Some(g));
        }
        out
    }

    /// Whether any element belongs to a group.
    pub fn any(&self) -> bool {
        !self.groups.is_empty()
    }

    /// For each + column of a pair, the column of its − half; None for every other column.
    pub fn minus_of(&self) -> Vec<Option<usize>> {
        let mut out = vec![None; self.of.len()];
        for g in &self.groups {
            for &(plus, minus) in &g.pairs {
                if let (Some(p), Some(m)) = (plus, minus) {
                    out[p] = Some(m);
                }
            }
        }
        out
    }

    /// For each column, (its coefficient, whether it is the − half), None outside groups.
    pub fn coefficient_of(&self) -> Vec<Option<(usize, bool)>> {
        let mut out = vec![None; self.of.len()];
        for g in &self.groups {
            for (c, &(plus, minus)) in g.pairs.iter().enumerate() {
                if let Some(p) = plus {
                    out[p] = Some((c, false));
                }
                if let Some(m) = minus {
                    out[m] = Some((c, true));
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(coupling: &[f64], knots: &Knots, j: usize, negative: bool) -> Element {
        Element { profile: Profile::Spline(knots.basis(j, negative)), coupling: coupling.to_vec(), offset: knots.lo }
    }

    #[test]
    fn a_cams_basis_columns_are_one_group_and_springs_their_own() {
        let k = Knots::over(-1.0, 1.0, 6, 0.0);
        let spring = Element { profile: Profile::Linear, coupling: vec![1.0, 0.0], offset: 0.0 };
        let mut elements = vec![(0usize, spring.clone())];
        for j in 0..k.basis_count() {
            for negative in [false, true] {
                elements.push((1, cam(&[1.0, -1.0], &k, j, negative)));
            }
        }
        // Another family's cam on the same coupling is another part; so is one on another coupling.
        elements.push((2, cam(&[1.0, -1.0], &k, 0, false)));
        elements.push((1, cam(&[0.0, 1.0], &k, 3, true)));
        elements.push((0, spring));
        let g = Grouping::new(elements.iter().map(|(f, e)| (*f, e)));
        assert_eq!(g.groups.len(), 3);
        assert_eq!(g.of[0], None);
        assert_eq!(g.of[1..=16], [Some(0); 16]);
        assert_eq!((g.of[17], g.of[18], g.of[19]), (Some(1), Some(2), None));
        let cam0 = &g.groups[0];
        assert_eq!(cam0.columns, (1..=16).collect::<Vec<_>>());
        assert_eq!(cam0.pairs.len(), 8);
        assert_eq!(cam0.pairs[3], (Some(7), Some(8)));
        assert!(cam0.uniform_gauge());
        assert_eq!(cam0.id(0), "C01");
        let minus = g.minus_of();
        assert_eq!((minus[7], minus[8], minus[0], minus[17]), (Some(8), None, None, None));
        assert_eq!(g.coefficient_of()[8], Some((3, true)));
        // Partition of unity: the roughness rows vanish on a constant and on a quadratic V.
        let rows = cam0.roughness_rows();
        assert_eq!(rows.len(), 5);
        assert!(rows.iter().all(|r| r.iter().sum::<f64>().abs() < 1e-9 * r.iter().map(|x| x.abs()).sum::<f64>()));
    }
}
