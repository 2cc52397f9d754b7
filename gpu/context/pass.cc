#include "gpu/context/pass.h"

#include <cstdlib>

#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
#include "gpu/context/gl_functions.h"

namespace mlclust::gpu {

absl::Status BeginPass(GlContext& context, absl::string_view pass) {
  MLCLUST_RETURN_IF_ERROR(context.MakeCurrent());
  const detail::GlFunctions& gl = context.gl();
  // Errors left by an earlier, failed pass must not be blamed on this one.
  for (int i = 0; i < 16 && gl.GetError() != GL_NO_ERROR; ++i) {
  }
  const char* fail = std::getenv(kFailPassVariable);
  if (fail != nullptr && (absl::string_view(fail) == pass || absl::string_view(fail) == "*")) {
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0xFFFFFFFFu, 0);  // GL_INVALID_VALUE
  }
  return absl::OkStatus();
}

absl::Status PassError(absl::string_view pass, const absl::Status& status) {
  if (status.ok()) return status;
  return absl::Status(status.code(), absl::StrCat("GPU pass '", pass, "': ", status.message()));
}

}  // namespace mlclust::gpu
