// assimp_io.hpp: the file access assimp gets when drape imports a mesh.
//
// assimp opens files on its own: the mesh file, and whatever that file names (an OBJ's
// material library, glTF buffers, textures). Its default IO system opens anything, so a
// material library that is a FIFO blocks the import forever and a device such as /dev/zero
// never ends. GuardedIOSystem opens regular files only (a FIFO is opened without blocking,
// seen to be a FIFO and closed), read-only, up to a size per file, and stops reading once
// an import has read a total budget of bytes. Every file it refused is recorded, so the
// caller can name it.
#pragma once

#include <assimp/IOStream.hpp>
#include <assimp/IOSystem.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace drape::io::detail {

class GuardedIOSystem final : public Assimp::IOSystem {
  public:
    /// maxFileBytes: the largest file opened; maxTotalBytes: the bytes all streams of this
    /// IO system may read together (reads beyond it return nothing, and budgetExceeded()).
    GuardedIOSystem(std::uint64_t maxFileBytes, std::uint64_t maxTotalBytes);
    ~GuardedIOSystem() override;

    bool Exists(const char* file) const override;
    char getOsSeparator() const override { return '/'; }
    Assimp::IOStream* Open(const char* file, const char* mode = "rb") override;
    void Close(Assimp::IOStream* stream) override;
    bool ComparePaths(const char* one, const char* second) const override;

    /// A file Open() refused, and why ("not a regular file (a FIFO)", "larger than ...").
    struct Refusal {
        std::string file;
        std::string reason;
    };
    const std::vector<Refusal>& refusals() const { return refusals_; }
    bool budgetExceeded() const { return budgetExceeded_; }
    std::uint64_t bytesRead() const { return bytesRead_; }

    /// Takes up to `want` bytes of the read budget; returns how many were granted.
    std::uint64_t charge(std::uint64_t want);

  private:
    void refuse(const char* file, std::string reason);

    std::uint64_t maxFileBytes_;
    std::uint64_t maxTotalBytes_;
    std::uint64_t bytesRead_ = 0;
    bool budgetExceeded_ = false;
    std::vector<Refusal> refusals_;
};

/// What a regular file is, opened without blocking: "regular file", "FIFO", "device"...
/// Returns an empty string for a regular file (size set), else what it is instead, or why
/// it could not be opened.
std::string describeNonRegular(const std::string& file, std::uint64_t& size);

} // namespace drape::io::detail
