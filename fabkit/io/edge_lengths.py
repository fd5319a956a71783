"""The edge-length file `fabkit relax --edge-lengths FILE.json` reads: edges to keep at given lengths.

Format: `{"edges": [[u, v], ...], "lengths": [m, ...]}` - 0-based vertex ids of the panel as loaded
(OBJ order), one length in metres per edge.
"""
from __future__ import annotations

from fabkit.errors import InputError

__all__ = ["kept_edge_lengths"]


def kept_edge_lengths(mesh, path=None, keep_boundary: bool = False) -> dict[int, float]:
    """`RelaxOptions.edge_lengths` ({edge id: length [m]}): every boundary edge at its length in
    `mesh` when `keep_boundary` (`fabkit relax --keep-boundary-lengths`), and the edges of the JSON
    file `path` (`--edge-lengths`; the file wins on overlap). `InputError` naming the file for a
    file that is not such a document or names an edge the mesh does not have."""
    import numpy as np

    from fabkit.io.jsonfile import load_json
    from fabkit.io.validate import check_coordinates

    kept: dict[int, float] = {}
    if keep_boundary:
        ids = np.flatnonzero(mesh.topology.boundary_edge_mask)
        kept.update(zip(ids.tolist(), mesh.edge_lengths[ids].tolist()))
    if path is None:
        return kept
    data = load_json(path, "JSON edge-length file")
    if not isinstance(data, dict) or not {"edges", "lengths"} <= set(data):
        raise InputError('expected an object {"edges": [[u, v], ...], "lengths": [...]}', source=path)
    try:
        pairs = np.asarray(data["edges"], dtype=np.float64)
        lengths = np.asarray(data["lengths"], dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError('"edges" must be pairs of vertex ids and "lengths" numbers', source=path) from None
    if pairs.ndim != 2 or pairs.shape[1] != 2 or lengths.ndim != 1 or len(lengths) != len(pairs):
        raise InputError(f'"edges" must be a list of [u, v] pairs with one length each (got {len(lengths)} '
                         f"lengths for {len(pairs) if pairs.ndim == 2 else '?'} edges)", source=path)
    check_coordinates(lengths, path, "edge length")
    if not np.all(np.isfinite(pairs) & (pairs == np.round(pairs))):
        raise InputError('"edges" must hold integer vertex ids', source=path)
    ids = mesh.topology.edge_ids(pairs.astype(np.int64))
    for (u, v), e, length in zip(pairs.astype(np.int64).tolist(), ids.tolist(), lengths.tolist()):
        if e < 0:
            raise InputError(f"[{u}, {v}] is not an edge of {mesh.n_vertices}-vertex mesh", source=path)
        if not (np.isfinite(length) and length > 0):
            raise InputError(f"edge [{u}, {v}]: length must be a positive number of metres, got {length}",
                             source=path)
        kept[e] = float(length)
    return kept
