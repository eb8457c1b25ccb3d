// assimp_io.cpp: GuardedIOSystem, assimp's file access for mesh import (see assimp_io.hpp).
#include "assimp_io.hpp"

#include <cerrno>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace drape::io::detail {

namespace {

std::string mib(std::uint64_t bytes) {
    if (bytes % (1024u * 1024u) != 0) return std::to_string(bytes) + " bytes";
    return std::to_string(bytes / (1024u * 1024u)) + " MiB";
}

/// What st_mode is, for messages about files that are not regular.
std::string kindOf(mode_t mode) {
    if (S_ISFIFO(mode)) return "a FIFO";
    if (S_ISCHR(mode)) return "a character device";
    if (S_ISBLK(mode)) return "a block device";
    if (S_ISSOCK(mode)) return "a socket";
    if (S_ISDIR(mode)) return "a folder";
    return "not a regular file";
}

/// Opens `file` read-only without ever blocking: O_NONBLOCK makes open() of a FIFO return
/// at once (a blocking open waits for a writer), and fstat then tells what it is. Returns
/// the descriptor of a regular file, or -1 with `why` set (and `missing` when there is no
/// such file).
int openRegular(const char* file, struct stat& st, std::string& why, bool& missing) {
    missing = false;
    const int fd = ::open(file, O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
    if (fd < 0) {
        missing = errno == ENOENT;
        why = std::strerror(errno);
        return -1;
    }
    if (::fstat(fd, &st) != 0) {
        why = std::strerror(errno);
        ::close(fd);
        return -1;
    }
    if (!S_ISREG(st.st_mode)) {
        why = "not a regular file (" + kindOf(st.st_mode) + ")";
        ::close(fd);
        return -1;
    }
    // Regular files ignore O_NONBLOCK; clear it anyway so reads behave as usual.
    const int flags = ::fcntl(fd, F_GETFL);
    if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
    return fd;
}

/// A read-only stream over a regular file. It never reads past the size the file had when
/// it was opened (a file that grows while it is read, or a /proc file whose size reads as
/// 0, cannot make it read forever), and every byte counts against its IO system's budget.
class GuardedStream final : public Assimp::IOStream {
  public:
    GuardedStream(int fd, std::uint64_t size, GuardedIOSystem& io)
        : fd_(fd), size_(size), io_(io) {}
    ~GuardedStream() override { ::close(fd_); }

    size_t Read(void* buffer, size_t size, size_t count) override {
        if (size == 0 || count == 0) return 0;
        // Whole items only, as fread: at most what is left of the file.
        const std::uint64_t left = size_ - pos_;
        std::uint64_t items = std::min<std::uint64_t>(count, left / size);
        items = io_.charge(items * size) / size;
        const std::uint64_t want = items * size;
        std::uint64_t got = 0;
        auto* out = static_cast<char*>(buffer);
        while (got < want) {
            const ssize_t n = ::pread(fd_, out + got, static_cast<size_t>(want - got),
                                      static_cast<off_t>(pos_ + got));
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) break; // an error or the file shrank: stop where it ended
            got += static_cast<std::uint64_t>(n);
        }
        pos_ += got;
        return static_cast<size_t>(got / size);
    }

    size_t Write(const void*, size_t, size_t) override { return 0; }

    aiReturn Seek(size_t offset, aiOrigin origin) override {
        // As fseek: the offset is added to the origin (a negative offset arrives wrapped
        // around, and wraps back here); the stream cannot move past the end.
        std::uint64_t base = 0;
        switch (origin) {
        case aiOrigin_SET:
            base = 0;
            break;
        case aiOrigin_CUR:
            base = pos_;
            break;
        case aiOrigin_END:
            base = size_;
            break;
        default:
            return aiReturn_FAILURE;
        }
        const std::uint64_t target = base + static_cast<std::uint64_t>(offset);
        if (target > size_) return aiReturn_FAILURE;
        pos_ = target;
        return aiReturn_SUCCESS;
    }

    size_t Tell() const override { return static_cast<size_t>(pos_); }
    size_t FileSize() const override { return static_cast<size_t>(size_); }
    void Flush() override {}

  private:
    int fd_;
    std::uint64_t size_;
    std::uint64_t pos_ = 0;
    GuardedIOSystem& io_;
};

} // namespace

GuardedIOSystem::GuardedIOSystem(std::uint64_t maxFileBytes, std::uint64_t maxTotalBytes)
    : maxFileBytes_(maxFileBytes), maxTotalBytes_(maxTotalBytes) {}

GuardedIOSystem::~GuardedIOSystem() = default;

bool GuardedIOSystem::Exists(const char* file) const {
    // stat never blocks, not even on a FIFO; Open decides what may be read.
    struct stat st;
    return file && ::stat(file, &st) == 0;
}

void GuardedIOSystem::refuse(const char* file, std::string reason) {
    for (const Refusal& r : refusals_)
        if (r.file == file && r.reason == reason) return; // importers probe a file repeatedly
    refusals_.push_back({file, std::move(reason)});
}

Assimp::IOStream* GuardedIOSystem::Open(const char* file, const char* mode) {
    if (!file) return nullptr;
    const std::string m = mode ? mode : "rb";
    if (m.find_first_of("wa+") != std::string::npos) {
        refuse(file, "opened for writing");
        return nullptr;
    }
    struct stat st;
    std::string why;
    bool missing = false;
    const int fd = openRegular(file, st, why, missing);
    if (fd < 0) {
        // A missing file is an ordinary answer (importers probe for optional files).
        if (!missing) refuse(file, why);
        return nullptr;
    }
    const auto size = static_cast<std::uint64_t>(st.st_size);
    if (size > maxFileBytes_) {
        ::close(fd);
        refuse(file, "larger than " + mib(maxFileBytes_));
        return nullptr;
    }
    return new GuardedStream(fd, size, *this);
}

void GuardedIOSystem::Close(Assimp::IOStream* stream) {
    delete stream;
}

bool GuardedIOSystem::ComparePaths(const char* one, const char* second) const {
    if (!one || !second) return false;
    if (std::strcmp(one, second) == 0) return true;
    char a[PATH_MAX], b[PATH_MAX];
    if (!::realpath(one, a) || !::realpath(second, b)) return false;
    return std::strcmp(a, b) == 0;
}

std::uint64_t GuardedIOSystem::charge(std::uint64_t want) {
    const std::uint64_t left = maxTotalBytes_ - bytesRead_;
    const std::uint64_t granted = std::min(want, left);
    if (granted < want) budgetExceeded_ = true;
    bytesRead_ += granted;
    return granted;
}

std::string describeNonRegular(const std::string& file, std::uint64_t& size) {
    struct stat st;
    std::string why;
    bool missing = false;
    const int fd = openRegular(file.c_str(), st, why, missing);
    if (fd < 0) return why;
    ::close(fd);
    size = static_cast<std::uint64_t>(st.st_size);
    return {};
}

} // namespace drape::io::detail
