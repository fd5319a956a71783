// Read a FOLD file with the reference JavaScript implementation (npm package `fold`) and print
// what it sees as JSON. Used by tests/test_fold.py: node read_with_fold_js.js <fold package dir> <file>
const FOLD = require(process.argv[2]);
const fs = require('fs');
const fold = JSON.parse(fs.readFileSync(process.argv[3], 'utf8'));
const out = {
  spec: fold.file_spec, creator: fold.file_creator, unit: fold.frame_unit,
  fileClasses: fold.file_classes, frameClasses: fold.frame_classes,
  numVertices: FOLD.filter.numVertices(fold),
  numEdges: FOLD.filter.numEdges(fold),
  numFaces: FOLD.filter.numFaces(fold),
  assigned: {},
  facesKeys: FOLD.filter.keysStartingWith(fold, 'faces_'),
  verticesKeys: FOLD.filter.keysStartingWith(fold, 'vertices_'),
  coords: fold.vertices_coords,
  foldAngle: fold.edges_foldAngle,
};
for (const a of ['B', 'M', 'V', 'F', 'J', 'U', 'C']) {
  out.assigned[a] = FOLD.filter.edgesAssigned(fold, a).length;
}
// orientation of every face in the key frame's xy plane (+1 = counter-clockwise)
out.faceOrientation = fold.faces_vertices.map(
  (f) => FOLD.geom.polygonOrientation(f.map((v) => fold.vertices_coords[v].slice(0, 2))));
// every face side must be an edge: faces_edges entries are undefined otherwise
const copy = FOLD.convert.deepCopy(fold);
FOLD.convert.faces_vertices_to_faces_edges(copy);
out.missingFaceSides = copy.faces_edges.reduce((n, fe) => n + fe.filter((e) => e === undefined).length, 0);
// faces the reference library finds in the planar graph of the key frame
const cp = {
  vertices_coords: fold.vertices_coords.map((c) => c.slice(0, 2)),
  edges_vertices: fold.edges_vertices,
};
FOLD.convert.edges_vertices_to_faces_vertices(cp);
out.recoveredFaces = cp.faces_vertices;
out.frames = (fold.file_frames || []).map((f) => ({
  parent: f.frame_parent, inherit: f.frame_inherit, classes: f.frame_classes,
  attributes: f.frame_attributes, coords: f.vertices_coords, foldAngle: f.edges_foldAngle,
}));
console.log(JSON.stringify(out));
