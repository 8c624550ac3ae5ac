#pragma once
// OpenGL helpers of the viewer (prt-relight view, docs/viewer.md).
//
// Contract: every function needs a current OpenGL 3.3+ core context with its entry
// points loaded (GLEW), and reports failures as prt::Error("OpenGL", ...): a shader
// that does not compile or a program that does not link (with the driver's log), a
// pending GL error (checkGl). Textures are GL_TEXTURE_2D, created bound, with nearest
// filtering, clamped edges and one mip level; uploads leave the texture bound and
// assume GL_UNPACK_ALIGNMENT 1.

#include <GL/glew.h>

#include <cstddef>
#include <vector>

namespace prt {

// Compiles the concatenation of `sources` (glShaderSource's list) as a shader of
// `type`; `name` names it in the error message.
GLuint compileShader(GLenum type, const std::vector<const char*>& sources, const char* name);

// Compiles and links a program of a vertex and a fragment shader, each made of the
// listed pieces; the shader objects are deleted once linked.
GLuint linkProgram(const std::vector<const char*>& vertex, const std::vector<const char*>& fragment,
                   const char* name);

// Throws when glGetError() reports an error; `where` says after what.
void checkGl(const char* where);

// A 2D texture of `rows` x width texels; data may be null.
GLuint makeTexture(GLint internalFormat, int width, int height, GLenum format, GLenum type, const void* data);

// Uploads `count` items (of `components` values each) into rows [firstRow, ...) of a
// texture `rowWidth` texels wide, item i at (i % rowWidth, firstRow + i / rowWidth).
template <class T>
void uploadRows(GLuint texture, int rowWidth, int firstRow, size_t count, GLenum format, GLenum type,
                const T* data, int components) {
    if (count == 0) return;
    glBindTexture(GL_TEXTURE_2D, texture);
    const size_t full = count / size_t(rowWidth), rest = count % size_t(rowWidth);
    if (full > 0)
        glTexSubImage2D(GL_TEXTURE_2D, 0, 0, firstRow, rowWidth, GLsizei(full), format, type, data);
    if (rest > 0)
        glTexSubImage2D(GL_TEXTURE_2D, 0, 0, firstRow + int(full), GLsizei(rest), 1, format, type,
                        data + full * size_t(rowWidth) * size_t(components));
}

}  // namespace prt
