// libFuzzer target: a file of one mesh format (DHFCAST_FUZZ_FORMAT, its extension) read as
// read_mesh() reads it, then validated as load_solid() validates it. Malformed data must end in
// Error{InvalidInput}; a crash, a leak, undefined behaviour or any other exception is a defect.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "dhfcast/error.h"
#include "dhfcast/mesh.h"
#include "readers.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  try {
    const dhfcast::TriMesh mesh =
        dhfcast::detail::mesh_from_data("fuzz." DHFCAST_FUZZ_FORMAT, bytes);
    dhfcast::validate_mesh(mesh);
  } catch (const dhfcast::Error& e) {
    if (e.code() != dhfcast::ErrorCode::InvalidInput) std::abort();
  }
  return 0;
}
