// The command-line and file checks every tool shares (core/cli.h, core/file_checks.h).
#include <tessera/core/cli.h>
#include <tessera/core/file_checks.h>

#include <gtest/gtest.h>

#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <fstream>

#include "../support/temp_dir.h"

namespace tessera::cli {
namespace {

TEST(Cli, IntegersNeverWrap) {
  uint32_t u = 7;
  EXPECT_FALSE(parseInteger<uint32_t>("4294967295", 0, 4294967295u, u));
  EXPECT_EQ(u, 4294967295u);
  for (const char* bad : {"4294967296", "4294967297", "-1", "+1", "1.5", "0x10", "1e3", "", " 1",
                          "1 ", "nan", "inf", "99999999999999999999999"}) {
    EXPECT_TRUE(parseInteger<uint32_t>(bad, 0, 4294967295u, u)) << bad;
  }
  uint64_t w = 0;
  EXPECT_TRUE(parseInteger<uint64_t>("18446744073709551616", 0, UINT64_MAX, w));
  EXPECT_TRUE(parseInteger<uint64_t>("-1", 0, UINT64_MAX, w));  // CLI11 takes it as 2^64 - 1
  int i = 0;
  EXPECT_FALSE(parseInteger<int>("-5", -10, 10, i));
  EXPECT_EQ(i, -5);
  EXPECT_EQ(parseInteger<int>("100000", 0, 256, i).value_or(""), "at most 256 (got 100000)");
  EXPECT_EQ(parseInteger<int>("-1", 0, 256, i).value_or(""), "at least 0 (got -1)");
}

TEST(Cli, ValidatorsRefuseNanAndInfinity) {
  for (const char* bad : {"nan", "-nan", "inf", "-inf", "1e400", "", "1,5", "abc"}) {
    std::string text = bad;
    EXPECT_FALSE(finiteRange(-1e9, 1e9)(text).empty()) << bad;
    text = bad;
    EXPECT_FALSE(positiveFinite(1e9)(text).empty()) << bad;
  }
  std::string zero = "0";
  EXPECT_FALSE(positiveFinite(1.0)(zero).empty());
  std::string ok = "0.5";
  EXPECT_TRUE(positiveFinite(1.0)(ok).empty());
  EXPECT_TRUE(finiteRange(0.0, 1.0)(ok).empty());
  std::string threads = "100000";
  EXPECT_EQ(integerRange(0, 256)(threads), "at most 256 (got 100000)");
}

TEST(Cli, SizesAndVectors) {
  const Size s = parseSize("1280x720", "--size", 16384);
  EXPECT_EQ(s.width, 1280u);
  EXPECT_EQ(s.height, 720u);
  for (const char* bad : {"4294967297x480", "0x480", "1x0", "-1x480", "x480", "480x", "1x2x3",
                          "16385x1", "nanx1", "1X2"}) {
    EXPECT_THROW(parseSize(bad, "--size", 16384), UsageError) << bad;
  }
  try {
    parseSize("4294967297x480", "--size", 16384);
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("--size 4294967297x480"), std::string::npos) << e.what();
  }
  EXPECT_EQ(parseVec3("1,-2.5,3e2", "--u"), glm::dvec3(1, -2.5, 300));
  for (const char* bad : {"nan,0,0", "0,inf,0", "1,2", "1,2,3,", "1,2,3,4", ",1,2", "a,b,c", ""})
    EXPECT_THROW(parseVec3(bad, "--u"), UsageError) << bad;
  EXPECT_THROW(parseVec3("5,-1,0.5", "--background", 0.0, 1.0), UsageError);
  EXPECT_EQ(parseVec3("1,0,0.5", "--background", 0.0, 1.0), glm::dvec3(1, 0, 0.5));
}

TEST(FileChecks, TheSameFileByAnyPath) {
  test::TempDir dir;
  const auto a = dir / "a.las";
  std::ofstream(a) << "x";
  std::filesystem::create_symlink(a, dir / "link.las");
  std::filesystem::create_hard_link(a, dir / "hard.las");
  std::ofstream(dir / "b.las") << "x";
  const std::vector<std::filesystem::path> inputs{a};
  for (const auto& same :
       {a, dir / "link.las", dir / "hard.las", dir / "." / "a.las", dir / "sub" / ".." / "a.las"}) {
    std::filesystem::create_directories(dir / "sub");
    EXPECT_EQ(sameFileAs(same, inputs), a) << same;
    EXPECT_THROW(refuseOverwrite(same, inputs, "-o"), UsageError) << same;
  }
  EXPECT_FALSE(sameFileAs(dir / "b.las", inputs));
  EXPECT_FALSE(sameFileAs(dir / "new.tlod", inputs));  // not there yet: nothing to lose
  EXPECT_NO_THROW(refuseOverwrite(dir / "new.tlod", inputs, "-o"));
}

TEST(FileChecks, OnlyRegularFilesOpen) {
  test::TempDir dir;
  const auto fifo = dir / "f.ply";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string why;
  // Would block forever in open() without O_NONBLOCK: no writer ever comes.
  EXPECT_EQ(openRegularFile(fifo, why), -1);
  EXPECT_NE(why.find("FIFO"), std::string::npos) << why;
  EXPECT_NE(notRegularFile(fifo).value_or("").find("FIFO"), std::string::npos);
  EXPECT_EQ(openRegularFile("/dev/zero", why), -1);
  EXPECT_NE(why.find("character device"), std::string::npos) << why;
  EXPECT_EQ(openRegularFile(dir.path(), why), -1);
  EXPECT_NE(why.find("directory"), std::string::npos) << why;
  EXPECT_EQ(openRegularFile(dir / "none", why), -1);
  EXPECT_NE(why.find("No such file"), std::string::npos) << why;
  // A socket.
  const int s = ::socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string sock = (dir / "s.ply").string();
  ASSERT_LT(sock.size(), sizeof addr.sun_path);
  std::copy(sock.begin(), sock.end(), addr.sun_path);
  ASSERT_EQ(::bind(s, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  EXPECT_NE(notRegularFile(sock).value_or("").find("socket"), std::string::npos);
  ::close(s);
  std::ofstream(dir / "r.ply") << "ply\n";
  const int fd = openRegularFile(dir / "r.ply", why);
  EXPECT_GE(fd, 0) << why;
  char c = 0;
  EXPECT_EQ(::read(fd, &c, 1), 1);  // a blocking, readable descriptor
  ::close(fd);
}

}  // namespace
}  // namespace tessera::cli
