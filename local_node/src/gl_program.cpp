// SPDX-License-Identifier: MIT
#include "gl_program.h"

#include <stdexcept>
#include <string>

namespace telex::local {
namespace {

GLuint compile(GLenum type, const char* source, std::string_view what) {
  const GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &source, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    glDeleteShader(s);
    throw std::runtime_error(std::string(what) + ": shader does not compile: " + log);
  }
  return s;
}

}  // namespace

GLuint link_program(const char* vertex_source, const char* fragment_source, std::string_view what) {
  const GLuint v = compile(GL_VERTEX_SHADER, vertex_source, what);
  const GLuint f = compile(GL_FRAGMENT_SHADER, fragment_source, what);
  const GLuint p = glCreateProgram();
  glAttachShader(p, v);
  glAttachShader(p, f);
  glLinkProgram(p);
  glDeleteShader(v);
  glDeleteShader(f);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetProgramInfoLog(p, sizeof log, nullptr, log);
    glDeleteProgram(p);
    throw std::runtime_error(std::string(what) + ": shaders do not link: " + log);
  }
  return p;
}

}  // namespace telex::local
