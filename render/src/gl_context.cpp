#include <tessera/render/gl_context.h>

#include <EGL/egl.h>
#include <EGL/eglext.h>
#define GL_GLEXT_PROTOTYPES
#include <GL/glcorearb.h>

namespace tessera::render {

std::unique_ptr<GlContext> GlContext::createHeadless() {
  auto get_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
      eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (!get_display)
    throw RenderError(
        "render::GlContext: EGL lacks eglGetPlatformDisplayEXT (install libegl-mesa0)");
  EGLDisplay display = get_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  EGLint major = 0, minor = 0;
  if (display == EGL_NO_DISPLAY || !eglInitialize(display, &major, &minor)) {
    throw RenderError(
        "render::GlContext: no surfaceless EGL display (Mesa's EGL_MESA_platform_surfaceless)");
  }
  std::unique_ptr<GlContext> ctx(new GlContext());
  ctx->mDisplay = display;
  if (!eglBindAPI(EGL_OPENGL_API))
    throw RenderError("render::GlContext: EGL cannot bind the OpenGL API");
  const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                            4,
                            EGL_CONTEXT_MINOR_VERSION,
                            5,
                            EGL_CONTEXT_OPENGL_PROFILE_MASK,
                            EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                            EGL_NONE};
  EGLContext context = eglCreateContext(display, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attribs);
  if (context == EGL_NO_CONTEXT) {
    throw RenderError("render::GlContext: no OpenGL 4.5 core context (EGL error " +
                      std::to_string(eglGetError()) + ")");
  }
  ctx->mContext = context;
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    throw RenderError("render::GlContext: cannot make the context current");
  }
  return ctx;
}

GlContext::~GlContext() {
  if (mDisplay) {
    eglMakeCurrent(mDisplay, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (mContext) eglDestroyContext(mDisplay, mContext);
    eglTerminate(mDisplay);
  }
}

std::string GlContext::description() const {
  auto str = [](GLenum e) {
    const GLubyte* s = glGetString(e);
    return s ? std::string(reinterpret_cast<const char*>(s)) : std::string("?");
  };
  return str(GL_RENDERER) + ", " + str(GL_VERSION);
}

}  // namespace tessera::render
