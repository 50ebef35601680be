// Boots @foxglove/studio-base 1.48's App as its own web package did (studio-web's Root), with the
// layout the page serves (layout.json) as the one layout in an in-memory layout storage. The data
// source comes from the address: ?ds=remote-file&ds.url=...&layoutId=seaway&time=...
(async function () {
  const S = window;
  const listeners = new Map();
  const values = new Map();
  const appConfiguration = {
    get: (k) => values.get(k),
    set: async (k, v) => { values.set(k, v); (listeners.get(k) || []).forEach((cb) => cb(v)); },
    addChangeListener: (k, cb) => listeners.set(k, [...(listeners.get(k) || []), cb]),
    removeChangeListener: (k, cb) => listeners.set(k, (listeners.get(k) || []).filter((c) => c !== cb)),
  };
  const layoutData = await (await fetch("layout.json")).json();
  const savedAt = new Date().toISOString();
  const store = new Map([["seaway", { id: "seaway", name: "seaway", permission: "CREATOR_WRITE",
    baseline: { data: layoutData, savedAt }, working: undefined, syncInfo: undefined }]]);
  const layoutStorage = {
    list: async () => [...store.values()],
    get: async (_ns, id) => store.get(id),
    put: async (_ns, layout) => { store.set(layout.id, layout); return layout; },
    delete: async (_ns, id) => { store.delete(id); },
    importLayouts: async () => {},
    migrateUnnamespacedLayouts: async () => {},
  };
  localStorage.setItem("studio.profile-data", JSON.stringify({ currentLayoutId: "seaway" }));
  await S.initI18n();
  const dataSources = [new S.RemoteDataSourceFactory(), new S.McapLocalDataSourceFactory(),
                       new S.FoxgloveWebSocketDataSourceFactory()];
  S.ReactDOM.createRoot(document.getElementById("root")).render(S.React.createElement(S.App, {
    deepLinks: [window.location.href], appConfiguration, dataSources, layoutStorage,
    extensionLoaders: [], enableLaunchPreferenceScreen: false, enableGlobalCss: true,
  }));
  window.seawayBooted = true;
})().catch((e) => { window.seawayBootError = String(e); console.error("boot failed", e); });
