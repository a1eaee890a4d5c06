// The mesh pass's floor (MeshPass::drawBare, bench/mesh_lod): GL's depth test and a constant
// colour, nothing else, so the pass's own cost shows against it.
layout(location = 0) out uint outColor;
layout(location = 1) out uint outPick;

void main() {
  outColor = 0xC8C8C8u;
  outPick = uint(gl_PrimitiveID);
}
