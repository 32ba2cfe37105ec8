"""Which contact rules are compiled in. Every rule is on by default; a rule switched off
compiles out (`ti.static`), which is how each rule's unit test shows the failure it prevents.
docs/method.md describes each rule and names its test."""

from dataclasses import dataclass, fields


@dataclass(frozen=True)
class ContactRules:
    """One flag per contact rule (True: the rule is applied).

    touching_pairs: a pair that only touches (one triangle in the other's plane) still gets a row
        from the crossing triangle's deepest vertex (contact.touching).
    pressed_through: with a soft body, a patch sagged wholly behind a face gets that row too.
    nearest_exit: a deep row between rigid or static bodies (or of a soft triangle in a rigid or
        static face) leaves through a convex neighbour's face when that is nearer (contact.exits).
    surface_points: rows whose point lies on the other body's surface are held there (grazing
        rows between moving bodies) or dropped when they did not approach (resting rows).
    moving_exit: between two moving bodies a row within the substep's allowance whose depth is
        mostly older than the substep leaves through the nearest convex neighbour's face as a
        deeper row does (contact.pair_rows).
    edge_edge_normal: two convex edges meeting push along their common normal.
    touching_rows: a row against a static body no deeper than rounding gives way to a vertex.
    duplicates: a point already a row of the same two bodies is not added twice.
    next_vertex: a duplicate's row goes to the next vertex of its triangle over the face.
    vertex_rows: every candidate vertex of a moved triangle gets a row, not only the deepest.
    soft_feature_rows: the other triangle's vertices behind a soft triangle get rows too.
    resting_rows: soft vertices just in front of a rigid or static face get rows.
    sharp_edge_rows: sharp convex edges under a soft triangle get rows.
    carried_rows: rows that pushed in one substep are offered again in the next.
    opposed_rows: a carried row is let go when a row of the same bodies pushes back against it.
    carried_hold: a row carried between two rigid bodies holds its gap instead of pushing out
        older depth (contact.carried).
    near_vertex: between two rigid bodies a point a hair from a vertex over the other face is that
        vertex, and its budget is not capped at its depth (contact.rows).
    shock_propagation: a light body under a much heavier one holds still in their contact.
    support_pass: after an island's sweeps, its rows that carry weight are projected once more
        level by level from the ground up, each lower body held still (solver.islands).
    gap_rows: between two moving rigid bodies a vertex just in front of the other's face gets a
        row that pushes once the projection closes the gap (contact.gap_rows; all-pairs scenes).
    """

    touching_pairs: bool = True
    pressed_through: bool = True
    nearest_exit: bool = True
    surface_points: bool = True
    moving_exit: bool = True
    edge_edge_normal: bool = True
    touching_rows: bool = True
    duplicates: bool = True
    next_vertex: bool = True
    vertex_rows: bool = True
    soft_feature_rows: bool = True
    resting_rows: bool = True
    sharp_edge_rows: bool = True
    carried_rows: bool = True
    opposed_rows: bool = True
    carried_hold: bool = True
    near_vertex: bool = True
    shock_propagation: bool = True
    support_pass: bool = True
    gap_rows: bool = True

    @classmethod
    def without(cls, *names: str) -> "ContactRules":
        """All rules but `names` (each a field name; ValueError for an unknown one)."""
        known = {f.name for f in fields(cls)}
        unknown = set(names) - known
        if unknown:
            raise ValueError(f"unknown contact rule(s) {sorted(unknown)}: {sorted(known)}")
        return cls(**{name: False for name in names})
