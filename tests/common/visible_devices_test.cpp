// The devices a run lets CUDA see (common/visible_devices.hpp): the restriction of each -device
// form, composed with the user's own CUDA_VISIBLE_DEVICES, and the user's names kept.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "common/visible_devices.hpp"

namespace qtmv {
namespace {

VisibleDevices plan(const std::string& device, const char* user = nullptr) {
  return plan_visible_devices(parse_device_spec(device), user);
}

TEST(VisibleDevices, OnlyTheDevicesAskedForInTheOrderAsked) {
  const VisibleDevices one = plan("cuda:2");
  EXPECT_TRUE(one.restricted);
  EXPECT_EQ(one.value, "2");
  EXPECT_EQ(one.named, (std::vector<int>{2}));
  EXPECT_EQ(one.ordinal_of(2), 0);   // the process's only device...
  EXPECT_EQ(one.user_of(0), 2);      // ...is the user's cuda:2
  EXPECT_EQ(one.ordinal_of(0), -1);  // hidden

  const VisibleDevices two = plan("cuda:3,1");
  EXPECT_EQ(two.value, "3,1");
  EXPECT_EQ(two.ordinal_of(3), 0);
  EXPECT_EQ(two.ordinal_of(1), 1);
  EXPECT_EQ(two.user_of(1), 1);

  EXPECT_EQ(plan("cuda").value, "0");
  EXPECT_EQ(plan("auto").value, "0");  // auto labels on the first GPU, if any
}

TEST(VisibleDevices, CpuAndAllLeaveCudaAsItIs) {
  for (const char* device : {"cpu", "cuda:all"}) {
    const VisibleDevices v = plan(device, "1,0");
    EXPECT_FALSE(v.restricted) << device;
    EXPECT_EQ(v.ordinal_of(3), 3) << device;
    EXPECT_EQ(v.user_of(2), 2) << device;
  }
}

TEST(VisibleDevices, ComposedWithTheUsersList) {
  // The user's cuda:N is the N-th entry of their list, index or UUID.
  EXPECT_EQ(plan("cuda:1", "3,2").value, "2");
  EXPECT_EQ(plan("cuda:1,0", " GPU-8932f937 , MIG-1234/1/0").value, "MIG-1234/1/0,GPU-8932f937");
  EXPECT_EQ(plan("cuda:1,0", "3,2").named, (std::vector<int>{1, 0}));
  // Past the user's list: -1 ends CUDA's enumeration there; the devices before it stay.
  const VisibleDevices past = plan("cuda:0,2", "3,1");
  EXPECT_EQ(past.value, "3,-1");
  EXPECT_EQ(past.named, (std::vector<int>{0}));
  EXPECT_EQ(past.ordinal_of(2), -1);
  EXPECT_EQ(plan("cuda:0", "").value, "-1");      // the user sees no device
  EXPECT_EQ(plan("cuda:1", "0,,1").value, "-1");  // an empty entry ends the user's list
}

TEST(VisibleDevices, TheFirstMissingDeviceIsNamed) {
  const DeviceSpec two = parse_device_spec("cuda:1,5");
  // Unrestricted, CUDA's count is the host's.
  const VisibleDevices none;
  EXPECT_EQ(first_missing_device(two, 4, none), 5);
  EXPECT_EQ(first_missing_device(two, 6, none), -1);
  EXPECT_EQ(first_missing_device(two, 0, none), 1);
  // Restricted, CUDA counts the devices asked for up to the first it cannot find.
  const VisibleDevices restricted = plan_visible_devices(two, nullptr);
  EXPECT_EQ(first_missing_device(two, 1, restricted), 5);
  EXPECT_EQ(first_missing_device(two, 2, restricted), -1);
  EXPECT_EQ(first_missing_device(two, 0, restricted), 1);
  const DeviceSpec all = parse_device_spec("cuda:all");
  EXPECT_EQ(first_missing_device(all, 0, none), 0);
  EXPECT_EQ(first_missing_device(all, 3, none), -1);
  EXPECT_EQ(first_missing_device(parse_device_spec("cpu"), 0, none), -1);
}

TEST(VisibleDevices, UnrestrictedNamesAreCudasOwn) {
  // No tool's main ran here: the process's names are CUDA's ordinals.
  EXPECT_FALSE(visible_devices().restricted);
  EXPECT_EQ(cuda_device_name(3), "cuda:3");
  EXPECT_EQ(cuda_ordinal(2), 2);
}

}  // namespace
}  // namespace qtmv
