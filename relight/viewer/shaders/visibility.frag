#version 330 core
out uint triangleId;
void main() { triangleId = uint(gl_PrimitiveID) + 1u; }
