#include "sempose/rt/thread_room.hpp"

#include <pthread.h>

#include <cerrno>
#include <cstring>
#include <vector>

namespace sempose::rt {

namespace {
// Each trial thread waits on the mutex the caller holds, so all of them exist at the same time.
void* wait_for_release(void* gate) {
  auto* m = static_cast<pthread_mutex_t*>(gate);
  pthread_mutex_lock(m);
  pthread_mutex_unlock(m);
  return nullptr;
}
}  // namespace

Status try_thread_room(int count, std::size_t stack_bytes, const std::string& what) {
  pthread_mutex_t gate = PTHREAD_MUTEX_INITIALIZER;
  pthread_mutex_lock(&gate);
  pthread_attr_t attr;
  pthread_attr_init(&attr);
  pthread_attr_setstacksize(&attr, stack_bytes);
  std::vector<pthread_t> made;
  int rc = 0;
  for (int i = 0; i < count && rc == 0; ++i) {
    pthread_t t;
    rc = pthread_create(&t, &attr, &wait_for_release, &gate);
    if (rc == 0) made.push_back(t);
  }
  pthread_attr_destroy(&attr);
  pthread_mutex_unlock(&gate);
  for (pthread_t t : made) pthread_join(t, nullptr);
  pthread_mutex_destroy(&gate);
  if (rc == 0) return Status::success();
  std::string why = what + ": cannot create its " + std::to_string(count) + " threads (" + std::to_string(made.size()) +
                    " could be made; pthread_create: " + std::strerror(rc) + ")";
  if (rc == EAGAIN || rc == ENOMEM) why += ": " + std::string(kThreadLimitHint);
  return Status::failure(why);
}

}  // namespace sempose::rt
