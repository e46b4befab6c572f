// Vigil's service worker: it makes the board installable and lets a phone show an alarm's
// system notification (registration.showNotification) and bring the board back on a tap.
// It caches nothing: an alarm board must never show a stale copy of itself.
self.addEventListener("install", () => self.skipWaiting());
self.addEventListener("activate", (event) => event.waitUntil(self.clients.claim()));
self.addEventListener("fetch", () => {});
self.addEventListener("notificationclick", (event) => {
  event.notification.close();
  const target = (event.notification.data && event.notification.data.url) || "/nurse";
  event.waitUntil(
    self.clients.matchAll({ type: "window", includeUncontrolled: true }).then((windows) => {
      for (const client of windows) {
        if (new URL(client.url).pathname.startsWith("/nurse") && "focus" in client) return client.focus();
      }
      return self.clients.openWindow(target);
    }),
  );
});
