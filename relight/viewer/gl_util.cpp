// OpenGL helpers of the viewer: see gl_util.h.

#include "relight/viewer/gl_util.h"

#include <algorithm>
#include <cstdio>
#include <string>

#include "common/error.h"

namespace prt {

GLuint compileShader(GLenum type, const std::vector<const char*>& sources, const char* name) {
    const GLuint s = glCreateShader(type);
    glShaderSource(s, GLsizei(sources.size()), sources.data(), nullptr);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        GLint length = 0;
        glGetShaderiv(s, GL_INFO_LOG_LENGTH, &length);
        std::string log(size_t(std::max(length, 1)), '\0');
        glGetShaderInfoLog(s, length, nullptr, log.data());
        glDeleteShader(s);
        throw Error("OpenGL", std::string("shader ") + name + " does not compile: " + log.c_str());
    }
    return s;
}

GLuint linkProgram(const std::vector<const char*>& vertex, const std::vector<const char*>& fragment,
                   const char* name) {
    const GLuint vs = compileShader(GL_VERTEX_SHADER, vertex, name);
    const GLuint fs = compileShader(GL_FRAGMENT_SHADER, fragment, name);
    const GLuint p = glCreateProgram();
    glAttachShader(p, vs);
    glAttachShader(p, fs);
    glLinkProgram(p);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        GLint length = 0;
        glGetProgramiv(p, GL_INFO_LOG_LENGTH, &length);
        std::string log(size_t(std::max(length, 1)), '\0');
        glGetProgramInfoLog(p, length, nullptr, log.data());
        glDeleteProgram(p);
        throw Error("OpenGL", std::string("program ") + name + " does not link: " + log.c_str());
    }
    return p;
}

void checkGl(const char* where) {
    const GLenum e = glGetError();
    if (e != GL_NO_ERROR) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "0x%04x", unsigned(e));
        throw Error("OpenGL", std::string("error ") + buf + " after " + where);
    }
}

GLuint makeTexture(GLint internalFormat, int width, int height, GLenum format, GLenum type, const void* data) {
    GLuint t = 0;
    glGenTextures(1, &t);
    glBindTexture(GL_TEXTURE_2D, t);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, 0);
    glTexImage2D(GL_TEXTURE_2D, 0, internalFormat, width, height, 0, format, type, data);
    return t;
}

}  // namespace prt
